"""House rules for the chapters: numbered, listed in the table of contents, same first cell,
committed executed and without stored errors, and their stored outputs produced by the code they
show. (nbmake executes them; this checks the files.)"""
import json
import os
import re
from pathlib import Path

import pytest

from tools.execute import data_fingerprint, stale_reason, stamp

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
SETUP = "from danae_lite.book import setup\ncfg = setup()"


def test_chapters_are_numbered_in_order_and_in_the_toc():
    numbers = [int(p.name[:2]) for p in NOTEBOOKS]
    assert numbers == list(range(1, len(numbers) + 1)), numbers
    toc = (ROOT / "_toc.yml").read_text()
    listed = re.findall(r"file:\s*notebooks/(\S+)", toc)
    assert listed == [p.stem for p in NOTEBOOKS]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_first_cell_outputs_and_errors(path):
    nb = json.loads(path.read_text())
    code = [c for c in nb["cells"] if c["cell_type"] == "code"]
    assert SETUP in "".join(code[0]["source"]), f"{path.name}: first code cell must be the common setup cell"
    assert nb["cells"][0]["cell_type"] == "markdown" and "".join(nb["cells"][0]["source"]).startswith(
        f"# {int(path.name[:2])}. "
    ), f"{path.name}: must open with its numbered title"
    # an empty cell (the student's, after an exercise) has nothing to execute and no count
    assert all(c.get("execution_count") for c in code if "".join(c["source"]).strip()), (
        f"{path.name}: committed without executing every cell")
    assert not any(o.get("output_type") == "error" for c in code for o in c.get("outputs", [])), path.name


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_no_stored_output_is_a_warning_on_stderr(path):
    # a library warning (e.g. tqdm's "IProgress not found") would show in the HTML book, with the
    # executing machine's paths, as if it concerned the reader
    nb = json.loads(path.read_text())
    stderr = [(i, "".join(o.get("text", ""))[:120]) for i, c in enumerate(nb["cells"]) if c["cell_type"] == "code"
              for o in c.get("outputs", []) if o.get("output_type") == "stream" and o.get("name") == "stderr"]
    assert not stderr, f"{path.name}: stderr output stored in (cell, text): {stderr}"


@pytest.fixture(scope="module")
def data_at_hand() -> str | None:
    """The fingerprint of the real data named by ``DANAE_DATA`` (None without it: the records
    are then checked for a fingerprint, not against the data)."""
    env = os.environ.get("DANAE_DATA")
    return data_fingerprint(env) if env and Path(env).is_dir() else None


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_outputs_match_the_code_and_data_they_were_executed_with(path, data_at_hand):
    reason = stale_reason(json.loads(path.read_text()), path.stem, data_at_hand)
    assert reason is None, reason


def test_the_staleness_check_accepts_a_fresh_record_only(tmp_path):
    copy = tmp_path / NOTEBOOKS[0].name
    copy.write_text(NOTEBOOKS[0].read_text())
    nb = json.loads(copy.read_text())
    nb.get("metadata", {}).pop("danae", None)
    assert "no execution record" in stale_reason(nb, copy.stem)

    stamp(nb, seconds=1.0, data_dir=tmp_path / "data", fast=False)
    assert "no fingerprint of the data" in stale_reason(nb, copy.stem)  # a record from before the field
    stamp(nb, seconds=1.0, data_dir=tmp_path / "data", fast=False, data_sha256="d1")
    copy.write_text(json.dumps(nb))
    stamped = json.loads(copy.read_text())
    assert stale_reason(stamped, copy.stem) is None
    assert stale_reason(stamped, copy.stem, "d1") is None
    assert "data it read differs from the data at hand" in stale_reason(stamped, copy.stem, "d2")

    prose = next(c for c in stamped["cells"] if c["cell_type"] == "markdown")
    prose["source"] = ["An edited paragraph."]
    assert stale_reason(stamped, copy.stem) is None

    code = [c for c in stamped["cells"] if c["cell_type"] == "code"]
    code[-1]["source"] = "".join(code[-1]["source"]) + "\nprint('edited')"
    reason = stale_reason(stamped, copy.stem)
    assert reason is not None and "code cells changed after its stored outputs were produced" in reason
    assert f"python -m tools.execute --only {copy.stem}" in reason and "make execute" in reason

    for data_dir, fast, words in ((None, False, "simulated data"), (tmp_path, True, "fast-mode")):
        fresh = json.loads(copy.read_text())
        stamp(fresh, seconds=1.0, data_dir=data_dir, fast=fast)
        assert words in stale_reason(fresh, copy.stem)


DRAWS = re.compile(r"^\s*(fig\b[\w\s,]*=|ax\s*=.*\.plot\.|plt\.show\(\))", re.M)
"""A code cell that makes or shows a figure (``fig = ...``, ``fig, ax = ...``, ``ax = df.plot.barh(...)``,
``plt.show()``)."""


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_every_figure_is_stored_as_an_image(path):
    # The book renders stored outputs only: a figure cell without a PNG output is a figure missing
    # from the book (e.g. a kernel run with MPLBACKEND=Agg draws into nothing).
    nb = json.loads(path.read_text())
    missing = [i for i, c in enumerate(nb["cells"]) if c["cell_type"] == "code" and DRAWS.search("".join(c["source"]))
               and not any("image/png" in o.get("data", {}) for o in c.get("outputs", []))]
    assert any(DRAWS.search("".join(c["source"])) for c in nb["cells"] if c["cell_type"] == "code"), path.name
    assert not missing, f"{path.name}: cells {missing} draw a figure but store no image; re-execute the chapter"


def test_make_test_starts_the_chapters_first_the_last_chapter_first():
    from types import SimpleNamespace

    from conftest import pytest_collection_modifyitems

    names = ["tests/test_a.py", "notebooks/01_x.ipynb", "tests/test_b.py", "notebooks/06_y.ipynb",
             "notebooks/05_z.ipynb", "tests/test_a.py"]
    items = [SimpleNamespace(path=Path(n), n=i) for i, n in enumerate(names)]
    pytest_collection_modifyitems(None, items)
    assert [i.n for i in items] == [3, 4, 1, 0, 2, 5]  # chapters 6, 5, 1, then the tests as collected
