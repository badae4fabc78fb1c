"""The re-execution command of the book (``python -m tools.execute``, ``make execute``).

Two tests start a kernel (a few seconds each); the others check what must happen before any
kernel starts: the safety rule, the code hash, the record and the command line.
"""
from __future__ import annotations

import json
import time
from datetime import datetime
from pathlib import Path

import nbformat
import pytest
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

import danae_lite
from tools import execute
from tools.execute import (BookExecutionError, code_hash, data_fingerprint, execute_book, execution_record, main,
                                stamp)

ROOT = Path(__file__).resolve().parents[1]


def write_notebook(path: Path, *sources: str) -> Path:
    """Write a notebook whose cells are ``sources`` (a leading ``#`` line makes a markdown cell)."""
    cells = [new_markdown_cell(s) if s.startswith("# ") else new_code_cell(s) for s in sources]
    nb = new_notebook(cells=cells, metadata={"kernelspec": {"name": "python3", "display_name": "Python 3",
                                                            "language": "python"}})
    path.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(nb, path)
    return path


@pytest.fixture
def no_kernel(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if a notebook is executed."""
    def refuse(*args: object, **kwargs: object) -> float:
        raise AssertionError("a notebook was executed")

    monkeypatch.setattr(execute, "execute_notebook", refuse)


def test_copies_are_executed_with_the_given_environment_and_stamped(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("DANAE_DATA", str(tmp_path))  # must not reach the kernel: data_dir=None
    monkeypatch.setenv("MPLBACKEND", "Agg")  # an inherited Agg must not stop the figures being stored
    src = write_notebook(
        tmp_path / "src" / "tiny.ipynb",
        "# Tiny",
        "import os\nprint(os.environ.get('DANAE_FAST'))\nprint(os.environ.get('DANAE_DATA'))\n"
        "print(os.environ['DANAE_CACHE'], os.environ['MPLBACKEND'], os.environ['PYTHONHASHSEED'])\n"
        "print(os.getcwd())",
        "6 * 7",
        "import matplotlib.pyplot as plt\nplt.plot([0, 1], [1, 0])\nplt.show()",
    )
    before = src.read_bytes()
    out, cache = tmp_path / "out", tmp_path / "cache"

    table = execute_book([src], data_dir=None, cache_dir=cache, fast=True, out_dir=out, timeout=120)

    assert src.read_bytes() == before
    printed = capsys.readouterr().out
    assert f"writing executed copies to {out}" in printed and "tiny: " in printed
    nb = nbformat.read(out / "tiny.ipynb", as_version=4)
    lines = nb.cells[1].outputs[0]["text"].splitlines()
    assert lines == ["1", "None", f"{cache.resolve()} {execute.INLINE_BACKEND} 0", str(src.parent.resolve())]
    assert nb.cells[2].outputs[0]["data"]["text/plain"] == "42"
    assert any("image/png" in o.get("data", {}) for o in nb.cells[3].outputs), "the figure was not stored"
    assert not any("execution" in c.metadata for c in nb.cells), "per-cell timestamps were stored"
    record = execution_record(nb)
    assert record is not None
    assert record["code_sha256"] == code_hash(nbformat.read(src, as_version=4)) == code_hash(nb)
    assert record["danae_lite_version"] == danae_lite.__version__
    assert (record["data"], record["data_dir"], record["fast"]) == ("simulated", "", True)
    assert record["seconds"] > 0
    assert datetime.fromisoformat(record["executed"]).utcoffset().total_seconds() == 0
    assert record["python"] and record["torch"]
    assert (record["networks_trained"], record["networks_cached"]) == (0, 0)  # a cache was given: counted
    assert table.to_dict("records") == [{"notebook": "tiny.ipynb", "seconds": record["seconds"],
                                         "networks_trained": 0, "networks_cached": 0,
                                         "data": "simulated", "fast": True,
                                         "written": str(out.resolve() / "tiny.ipynb")}]


def test_a_failing_cell_names_the_notebook_and_leaves_it_untouched(tmp_path):
    src = write_notebook(tmp_path / "nbs" / "broken.ipynb", "# Broken", "x = 1", "raise ValueError('boom')")
    before = src.read_bytes()
    data = tmp_path / "data"
    data.mkdir()

    with pytest.raises(BookExecutionError, match=r"broken\.ipynb: cell 2 failed: ValueError: boom"):
        execute_book([src], data_dir=data, cache_dir=None, fast=False, timeout=120, progress=False)

    assert src.read_bytes() == before
    assert sorted(p.name for p in src.parent.iterdir()) == ["broken.ipynb"]  # no temporary file left


@pytest.mark.parametrize(("has_data", "fast", "reason"), [
    (False, False, "without real data"),
    (True, True, "in fast mode"),
    (False, True, "without real data .* and in fast mode"),
])
def test_in_place_runs_without_real_data_or_in_fast_mode_are_refused(tmp_path, no_kernel, has_data, fast,
                                                                     reason):
    src = write_notebook(tmp_path / "nbs" / "chapter.ipynb", "# Chapter", "print(1)")
    before = src.read_bytes()
    start = time.perf_counter()
    for out_dir in (None, src.parent):  # copies into the notebook's own folder are in place too
        with pytest.raises(BookExecutionError, match=f"{reason}.*--out DIR") as err:
            execute_book([src], data_dir=tmp_path if has_data else None, cache_dir=tmp_path / "cache",
                         fast=fast, out_dir=out_dir, progress=False)
        assert "replace" in str(err.value) and "\n" not in str(err.value)
    assert time.perf_counter() - start < 2.0
    assert src.read_bytes() == before
    assert not (tmp_path / "cache").exists()


def test_code_hash_follows_the_code_cells_only():
    nb = new_notebook(cells=[new_markdown_cell("# Title"), new_code_cell("a = 1\nb = 2"),
                             new_code_cell("a + b")])
    ref = code_hash(nb)
    assert len(ref) == 64 and int(ref, 16) >= 0

    as_json = json.loads(nbformat.writes(nb))  # sources stored as lists of lines
    assert isinstance(as_json["cells"][1]["source"], list) and code_hash(as_json) == ref

    nb.cells[0].source = "# Another title\n\nMore prose."
    nb.cells[1].outputs = [nbformat.v4.new_output("stream", text="x")]
    nb.metadata["danae"] = {"execution": {"code_sha256": "0"}}
    assert code_hash(nb) == ref

    nb.cells[2].source = "a - b"
    assert code_hash(nb) != ref
    moved = new_notebook(cells=[new_code_cell("a = 1"), new_code_cell("b = 2\na + b")])
    assert code_hash(moved) != ref  # the same text split differently between cells


def test_stamp_keeps_only_the_name_of_the_data_folder(tmp_path):
    nb = new_notebook(cells=[new_code_cell("1")])
    assert execution_record(nb) is None
    record = stamp(nb, seconds=12.345, data_dir=tmp_path / "shared" / "data", fast=False)
    assert execution_record(nb) == record
    assert (record["data"], record["data_dir"], record["fast"]) == ("real", "data", False)
    assert record["seconds"] == 12.3
    assert "networks_trained" not in record  # not counted
    counted = stamp(nb, seconds=1.0, data_dir=None, fast=True, networks=(7, 6), data_sha256="ignored")
    assert (counted["networks_trained"], counted["networks_cached"]) == (7, 6)
    assert counted["data_sha256"] == ""  # the simulator has no data to fingerprint
    assert str(tmp_path) not in json.dumps(nb.metadata)


def test_the_data_fingerprint_follows_the_content_and_names_not_the_location(tmp_path):
    import hashlib

    def make(root: Path, text: bytes = b"1,2,3\n") -> Path:
        (root / "oxiod" / "handheld").mkdir(parents=True)
        (root / "oxiod" / "handheld" / "imu2.csv").write_bytes(text)
        (root / "notes.txt").write_text("not a dataset folder")
        return root

    a = data_fingerprint(make(tmp_path / "a"))
    expected = hashlib.sha256(b"oxiod/handheld/imu2.csv\0" + hashlib.sha256(b"1,2,3\n").digest()).hexdigest()
    assert a == expected  # path relative to the data folder, then the content's digest
    assert data_fingerprint(make(tmp_path / "b")) == a  # another location, the same data
    assert data_fingerprint(make(tmp_path / "c", b"1,2,4\n")) != a  # one byte edited
    (tmp_path / "b" / "oxiod" / "handheld" / "imu2.csv").rename(tmp_path / "b" / "oxiod" / "handheld" / "imu3.csv")
    assert data_fingerprint(tmp_path / "b") != a  # renamed
    (tmp_path / "a" / "notes.txt").write_text("edited")
    assert data_fingerprint(tmp_path / "a") == a  # outside the dataset folders
    assert data_fingerprint(None) == ""


def test_the_toc_lists_every_chapter_in_order():
    stems = sorted(p.stem for p in (ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
    assert execute.toc_chapters(ROOT) == stems


def test_cli_missing_data_dir_is_one_line_and_exit_2(tmp_path, monkeypatch, capsys, no_kernel):
    monkeypatch.chdir(ROOT / "notebooks")  # the repository root is found upward
    assert main(["--data-dir", str(tmp_path / "missing"), "--only", "01_kalman_filter"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and "missing" in err


def test_cli_refuses_in_place_without_data_and_rejects_unknown_chapters(tmp_path, monkeypatch, capsys,
                                                                        no_kernel):
    monkeypatch.chdir(ROOT)
    monkeypatch.delenv("DANAE_DATA", raising=False)
    monkeypatch.delenv("DANAE_FAST", raising=False)
    monkeypatch.setenv("DANAE_CACHE", str(tmp_path / "cache"))
    assert main(["--only", "01_kalman_filter"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "refusing" in err and "--out DIR" in err
    assert main(["--only", "07_nothing"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "07_nothing" in err and "01_kalman_filter" in err
    assert not (tmp_path / "cache").exists()


def test_cli_help_explains_the_safety_rule(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--help"])
    assert done.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "rewritten in place only for a full-mode run with real data" in text and "--out DIR" in text


def _book_root(tmp_path: Path, fresh: bool) -> Path:
    """A repository root with a _toc.yml and two chapters: 01_one stamped by a full-mode, real-data
    run of its code (fresh when ``fresh``), 02_two never executed (stale)."""
    root = tmp_path / "repo"
    (root / "notebooks").mkdir(parents=True)
    (root / "_toc.yml").write_text("format: jb-book\nroot: intro\nchapters:\n"
                                   "  - file: notebooks/01_one\n  - file: notebooks/02_two\n")
    one = write_notebook(root / "notebooks" / "01_one.ipynb", "# 1. One", "print(1)")
    write_notebook(root / "notebooks" / "02_two.ipynb", "# 2. Two", "print(2)")
    if fresh:
        nb = nbformat.read(one, as_version=4)
        stamp(nb, seconds=1.0, data_dir=tmp_path / "data", fast=False, data_sha256=data_fingerprint(tmp_path / "data"))
        nbformat.write(nb, one)
    return root


@pytest.mark.parametrize(("argv", "fresh", "expected"), [
    ([], True, ["02_two"]),                      # the stale chapter only
    ([], False, ["01_one", "02_two"]),
    (["--all"], True, ["01_one", "02_two"]),     # forced
    (["--only", "01_one"], True, ["01_one"]),    # named: run even though fresh
])
def test_make_execute_runs_the_stale_chapters_unless_told_otherwise(tmp_path, monkeypatch, capsys, argv, fresh,
                                                                    expected):
    root = _book_root(tmp_path, fresh)
    (tmp_path / "data").mkdir()
    monkeypatch.chdir(root)
    monkeypatch.setenv("DANAE_DATA", str(tmp_path / "data"))
    monkeypatch.delenv("DANAE_FAST", raising=False)
    monkeypatch.setenv("DANAE_CACHE", str(tmp_path / "cache"))
    ran: list[list[str]] = []
    monkeypatch.setattr(execute, "execute_book", lambda paths, **kw: ran.append([Path(p).stem for p in paths]))
    assert main(argv) == 0
    assert ran == [expected]
    if fresh and not argv:
        assert "up to date, left as they are: 01_one" in capsys.readouterr().out


def test_make_execute_with_nothing_stale_runs_nothing(tmp_path, monkeypatch, capsys):
    root = _book_root(tmp_path, fresh=True)
    two = root / "notebooks" / "02_two.ipynb"
    nb = nbformat.read(two, as_version=4)
    stamp(nb, seconds=1.0, data_dir=tmp_path / "data", fast=False, data_sha256=data_fingerprint(tmp_path / "data"))
    nbformat.write(nb, two)
    (tmp_path / "data").mkdir()
    monkeypatch.chdir(root)
    monkeypatch.setenv("DANAE_DATA", str(tmp_path / "data"))  # the data the records were stamped with
    monkeypatch.setattr(execute, "execute_book", lambda *a, **kw: pytest.fail("nothing is stale"))
    assert main([]) == 0
    assert "nothing to re-execute" in capsys.readouterr().out


def test_cold_runs_in_a_new_cache_that_is_removed_afterwards(tmp_path, monkeypatch):
    root = _book_root(tmp_path, fresh=False)
    (tmp_path / "data").mkdir()
    monkeypatch.chdir(root)
    monkeypatch.setenv("DANAE_DATA", str(tmp_path / "data"))
    monkeypatch.setenv("DANAE_CACHE", str(tmp_path / "warm"))
    seen: list[Path] = []

    def fake(paths, *, cache_dir, **kw):
        seen.append(Path(cache_dir))
        assert Path(cache_dir).is_dir() and not any(Path(cache_dir).iterdir())

    monkeypatch.setattr(execute, "execute_book", fake)
    assert main(["--cold"]) == 0
    assert len(seen) == 1 and seen[0] != tmp_path / "warm" and not seen[0].exists()


def test_cold_with_a_cache_folder_trains_there_and_keeps_it(tmp_path, monkeypatch, capsys):
    root = _book_root(tmp_path, fresh=False)
    (tmp_path / "data").mkdir()
    monkeypatch.chdir(root)
    monkeypatch.setenv("DANAE_DATA", str(tmp_path / "data"))
    seen: list[Path] = []

    def fake(paths, *, cache_dir, cold, **kw):
        seen.append(Path(cache_dir))
        assert cold and not any(Path(cache_dir).iterdir())
        (Path(cache_dir) / "net.pt").write_bytes(b"x")

    monkeypatch.setattr(execute, "execute_book", fake)
    kept = tmp_path / "new" / "cache"
    assert main(["--cold", "--cache", str(kept)]) == 0
    assert seen == [kept] and (kept / "net.pt").exists()     # kept for later warm runs
    # a second cold run into the same, now full, folder is refused before anything runs
    assert main(["--cold", "--cache", str(kept)]) == 2 and len(seen) == 1
    assert f"--cold --cache {kept}: a cold run needs an empty or absent folder" in capsys.readouterr().err


def test_network_counts_tell_trained_from_loaded_files():
    before = {"a.pt": 10.0, "b.pt": 10.0, "c.pt": 10.0}
    after = {"a.pt": 10.0, "b.pt": 25.0, "c.pt": 30.0, "d.pt": 31.0, "e.pt": 32.0}   # b, c loaded; d, e new
    assert execute._network_counts(before, after, start=20.0) == (2, 2)
    assert execute._network_counts({}, {}, start=0.0) == (0, 0)


def test_a_run_counts_the_networks_it_trained_and_loaded(tmp_path):
    src = write_notebook(
        tmp_path / "nbs" / "nets.ipynb", "# Networks",
        "from danae_lite.book import setup\ncfg = setup(verbose=False)",
        "import numpy as np\nfrom danae_lite.danae import networks\nfrom danae_lite.danae.train_types import TrainConfig\n"
        "x = [np.sin(np.linspace(0.0, 20.0, 300))]\n"
        "nets = networks.train_networks({'roll': x}, {'roll': x}, TrainConfig(max_steps=2, num_threads=1), (0, 1),"
        " cache=cfg.cache)",
    )
    cache = tmp_path / "cache"
    first = execute_book([src], data_dir=None, cache_dir=cache, fast=True, out_dir=tmp_path / "a", progress=False,
                         cold=True)
    again = execute_book([tmp_path / "a" / "nets.ipynb"], data_dir=None, cache_dir=cache, fast=True,
                         out_dir=tmp_path / "b", progress=False)
    assert first[["networks_trained", "networks_cached"]].values.tolist() == [[2, 0]]  # cold
    assert again[["networks_trained", "networks_cached"]].values.tolist() == [[0, 2]]  # warm
    assert len(list((cache / "fast").glob("networks/*/output.pkl"))) == 2 and not (cache / "full").exists()
    warm_nb = nbformat.read(tmp_path / "b" / "nets.ipynb", as_version=4)
    record = execution_record(warm_nb)
    assert (record["networks_trained"], record["networks_cached"]) == (0, 2)
    # under which conditions: the kernel's environment (fast mode, one job, OMP_NUM_THREADS
    # as make test sets it or the machine's default) and the load around the run
    held = record["conditions"]
    assert set(held) == {"cpu", "cores", "onednn_isa", "torch_threads", "jobs", "load_start", "load_end"}
    assert held["jobs"] == 1 and held["cores"] >= 1 and held["onednn_isa"] and held["cpu"]
    assert held["load_start"] >= 0 and held["load_end"] >= 0
    # the cold run's record is kept beside the warm one: the chapter can state both
    cold = execute.cold_record(warm_nb)
    assert cold == execution_record(nbformat.read(tmp_path / "a" / "nets.ipynb", as_version=4))
    assert (cold["networks_trained"], cold["networks_cached"]) == (2, 0)
    (_, listed), = execute.chapter_records([tmp_path / "b" / "nets.ipynb"])
    assert listed["cold"] == cold and listed["seconds"] == record["seconds"]
    # the warm run is kept too, and stays through the next cold run (in a new empty cache)
    assert execute.warm_record(warm_nb) == record and execute.warm_record(
        nbformat.read(tmp_path / "a" / "nets.ipynb", as_version=4)) is None
    execute_book([tmp_path / "b" / "nets.ipynb"], data_dir=None, cache_dir=tmp_path / "cache2", fast=True,
                 out_dir=tmp_path / "c", progress=False, cold=True)
    again_cold = nbformat.read(tmp_path / "c" / "nets.ipynb", as_version=4)
    assert execute.warm_record(again_cold) == record
    assert execute.cold_record(again_cold) == execution_record(again_cold) != cold


def test_kept_records_of_other_code_or_data_are_dropped():
    """A cold or warm record kept from a run of other code cells (or other data) timed other
    outputs: the next run drops it instead of stating it beside the new outputs."""
    old = {"code_sha256": "a" * 64, "data_sha256": "d", "data": "real", "fast": False,
           "seconds": 50.0, "networks_trained": 0, "networks_cached": 6}
    nb = {"metadata": {"danae": {"cold_execution": {**old, "networks_trained": 6, "networks_cached": 0},
                                 "warm_execution": dict(old)}}}
    same_code = {**old, "seconds": 40.0, "networks_trained": 3, "networks_cached": 3}
    execute.keep_run(nb, same_code, cold=False)         # neither cold nor warm: both kept
    assert set(nb["metadata"]["danae"]) == {"cold_execution", "warm_execution"}
    new_code = {**old, "code_sha256": "b" * 64, "seconds": 45.0}
    execute.keep_run(nb, new_code, cold=False)          # warm, other code: the old cold record goes
    assert nb["metadata"]["danae"] == {"warm_execution": new_code}
    other_data = {**new_code, "data_sha256": "e", "networks_trained": 6, "networks_cached": 0}
    execute.keep_run(nb, other_data, cold=True)
    assert nb["metadata"]["danae"] == {"cold_execution": other_data}


# ---- the conditions a run's numbers hold under ---------------------------------------------

def test_the_cpu_model_comes_from_cpuinfo():
    from tools.conditions import cpu_model

    assert cpu_model("processor\t: 0\nmodel name\t: AMD EPYC 7B13\nflags\t: avx2\n") == "AMD EPYC 7B13"
    assert cpu_model("processor\t: 0\n")  # what platform says, or "unknown CPU"


def test_the_probe_output_is_parsed_or_refused():
    from tools.conditions import parse_probe

    out = ("onednn_verbose,v1,info,oneDNN v3.12.0 (commit 80afa71)\n"
           "onednn_verbose,v1,info,cpu,runtime:OpenMP,nthr:2\n"
           "onednn_verbose,v1,info,cpu,isa:Intel AVX-512 with AVX512BW, AVX512VL, and AVX512DQ extensions\n"
           "torch_threads 2\n")
    assert parse_probe(out) == {"onednn_isa": "Intel AVX-512 with AVX512BW, AVX512VL, and AVX512DQ extensions",
                                "torch_threads": 2}
    with pytest.raises(ValueError, match="no instruction set or thread count"):
        parse_probe("torch_threads 2\n")


def test_the_probe_sees_the_kernels_environment():
    """The probe runs in the environment it is given: a thread count and an instruction-set cap
    set there are what it reports."""
    import os

    from tools.conditions import probe

    cpuinfo = Path("/proc/cpuinfo")
    if not cpuinfo.exists() or "avx2" not in cpuinfo.read_text(errors="replace"):
        pytest.skip("no AVX2 on this CPU (or no /proc/cpuinfo): oneDNN cannot be capped at it")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "ONEDNN_MAX_CPU_ISA": "AVX2", "DANAE_JOBS": "3"}
    held = probe(env)
    assert (held["torch_threads"], held["jobs"]) == (1, 3)
    assert held["onednn_isa"] == "Intel AVX2"
