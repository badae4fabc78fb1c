"""The verdict tables the chapters store agree with the rule: each glued verdict names a direction
exactly when its glued interval excludes zero (danae_lite.evaluate.comparison)."""
from __future__ import annotations

import ast
import json
import math
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))


def glued(path: Path) -> dict[str, str]:
    """Name -> stored text (Markdown, else plain) of every value a chapter glues."""
    out = {}
    for cell in json.loads(path.read_text(encoding="utf-8"))["cells"]:
        for o in cell.get("outputs", []):
            name = o.get("metadata", {}).get("scrapbook", {}).get("name")
            if name:
                data = o.get("data", {})
                pre = o["metadata"]["scrapbook"].get("mime_prefix", "")
                text = data.get(pre + "text/markdown", data.get(pre + "text/plain", ""))
                text = "".join(text) if isinstance(text, list) else text
                try:   # a glued str is stored as its repr
                    value = ast.literal_eval(text)
                    out[name] = value if isinstance(value, str) else text
                except (ValueError, SyntaxError):
                    out[name] = text
    return out


def verdict_rows(values: dict[str, str], unit: str = "pct") -> dict[str, tuple[str, float, float]]:
    """Row stem -> (verdict, low, high) for every glued ``<stem>_verdict`` with its interval
    ``<stem>_low_<unit>``..``<stem>_high_<unit>`` (``pct``: a change [%]; ``pts``: a coverage
    shortfall [percentage points])."""
    rows = {}
    for name, text in values.items():
        stem = name.removesuffix("_verdict")
        if stem != name and f"{stem}_low_{unit}" in values and f"{stem}_high_{unit}" in values:
            rows[stem] = (text.strip(), float(values[f"{stem}_low_{unit}"]), float(values[f"{stem}_high_{unit}"]))
    return rows


def disagreements(rows: dict[str, tuple[str, float, float]]) -> list[str]:
    bad = []
    for stem, (verdict, low, high) in rows.items():
        if math.isnan(low) or math.isnan(high):
            ok = verdict == "numbers only"
        elif verdict in ("lower error", "goal met") or verdict.startswith("lower error"):
            ok = high < 0
        elif verdict in ("higher error", "covers more"):
            ok = low > 0
        elif verdict == "covers less":
            ok = high < 0
        elif verdict.startswith("no worse than "):
            ok = 0 <= high < float(verdict.removeprefix("no worse than ").removesuffix(" %"))
        else:   # no clear difference
            ok = low <= 0 <= high
        if not ok:
            bad.append(f"{stem}: {verdict!r} with interval {low:+.1f} to {high:+.1f} %")
    return bad


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_each_stored_verdict_names_a_direction_exactly_when_its_interval_excludes_zero(path):
    values = glued(path)
    assert disagreements(verdict_rows(values)) == []
    assert disagreements(verdict_rows(values, "pts")) == []


def test_the_chapters_store_verdict_tables():
    stems = {p.stem: len(verdict_rows(glued(p))) for p in NOTEBOOKS}
    assert stems["05_baselines_leaderboard"] >= 8 and stems["06_cross_validation"] >= 20
    assert stems["07_danae_res"] >= 40 and stems["08_no_harm"] >= 20
    assert len(verdict_rows(glued(ROOT / "notebooks" / "08_no_harm.ipynb"), "pts")) >= 8


def test_the_check_finds_a_verdict_its_interval_contradicts():
    rows = verdict_rows({"a_verdict": "lower error", "a_low_pct": "-30.0", "a_high_pct": "4.0",
                         "b_verdict": "no clear difference", "b_low_pct": "-3.0", "b_high_pct": "5.0",
                         "c_verdict": "numbers only", "c_low_pct": "nan", "c_high_pct": "nan",
                         "d_verdict": "higher error", "d_low_pct": "-1.0", "d_high_pct": "9.0",
                         "e_verdict": "no worse than 2 %", "e_low_pct": "-1.0", "e_high_pct": "1.5",
                         "f_verdict": "no worse than 2 %", "f_low_pct": "-1.0", "f_high_pct": "2.5",
                         "g_verdict": "covers less", "g_low_pct": "-9.0", "g_high_pct": "1.0"})
    assert [b.split(":")[0] for b in disagreements(rows)] == ["a", "d", "f", "g"]
