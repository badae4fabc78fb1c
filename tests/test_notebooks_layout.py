"""House rules for the chapters: numbered, listed in the table of contents, same first cell,
committed executed and without stored errors. (nbmake executes them; this checks the files.)"""
import json
import re
from pathlib import Path

import pytest

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
    assert all(c.get("execution_count") for c in code), f"{path.name}: committed without executing every cell"
    assert not any(o.get("output_type") == "error" for c in code for o in c.get("outputs", [])), path.name
