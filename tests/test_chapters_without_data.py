"""Every chapter a second time, in fast mode with no data folder, as a reader without the real
recordings runs it: the simulator stands in (the run's record says ``"simulated"``), and every
figure must name that data, not real data (:func:`test_notebook_rendering.caption_problems`).

The first run of the chapters in ``make test`` (nbmake, fast mode) reads ``DANAE_DATA`` when it
is set; this one never does. It writes the executed copies to a temporary folder and leaves the
committed notebooks as they are. Networks come from the fast cache when they are there.
"""
from __future__ import annotations

import json

import pytest

from danae_lite import runtime
from tools import execute

from test_notebook_prose import NOTEBOOKS, figure_problems
from test_notebook_rendering import caption_problems


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_a_chapter_run_without_data_names_the_simulator_in_its_captions(path, tmp_path):
    run = execute.execute_book([path], data_dir=None, cache_dir=runtime.cache_dir(), fast=True,
                               out_dir=tmp_path, timeout=600, progress=False)
    out = tmp_path / path.name
    notebook = json.loads(out.read_text())
    assert run.loc[0, "data"] == notebook["metadata"]["danae"]["execution"]["data"] == "simulated"
    problems = caption_problems(notebook) + figure_problems(out)
    assert not problems, f"{path.name} without data:\n" + "\n".join(problems)
