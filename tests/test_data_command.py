"""``python -m danae_lite data where|check|fetch``: the inventory against the book's reference copies
(synthetic copies everywhere, the real ones where DANAE_DATA has them) and the BROAD download
against a local HTTP server on the loopback address (a good file, a truncated transfer and a
file with another checksum). Every folder written is a temporary one."""
from __future__ import annotations

import http.server
import os
import shutil
import threading
from pathlib import Path

import pytest

from danae_lite.cli import main
from danae_lite.data import fetch, inventory
from danae_lite.data.inventory import ReferenceFile
from conftest import edit_cell, write_ucs
from tools.data_registry import entry, reference_paths


def handheld_reference(data_dir: Path) -> list[ReferenceFile]:
    """A reference copy made of the synthetic handheld files (the book's registry has the real ones)."""
    rels = [rel for ds, rel in reference_paths(data_dir) if ds == "oxiod handheld"]
    return [ReferenceFile(**entry(data_dir, "oxiod handheld", rel)) for rel in rels]


def statuses(reports: list[inventory.DatasetReport]) -> dict[str, str]:
    return {f.path.name: f.status for r in reports for f in r.files}


def test_an_unchanged_copy_is_the_books(tmp_oxiod):
    reports = inventory.check(tmp_oxiod.data_dir, ("oxiod",), handheld_reference(tmp_oxiod.data_dir))
    assert set(statuses(reports).values()) == {"ok"} and len(statuses(reports)) == 8
    assert not any(r.failed for r in reports)  # trolley and multi users: absent, optional


def test_missing_truncated_and_edited_files_are_named(tmp_oxiod):
    ref = handheld_reference(tmp_oxiod.data_dir)
    syn = tmp_oxiod.syn
    (syn / "vi3.csv").unlink()
    raw = (syn / "imu4.csv").read_bytes()
    (syn / "imu4.csv").write_bytes(raw[: len(raw) // 2])  # cut inside a line
    edit_cell(syn / "vi7.csv", 5, 2, "0.5")  # still a valid file, not the book's
    reports = inventory.check(tmp_oxiod.data_dir, ("oxiod",), ref)
    got = statuses(reports)
    assert got == {"imu2.csv": "ok", "vi2.csv": "ok", "imu3.csv": "ok", "vi3.csv": "missing",
                   "imu4.csv": "malformed", "vi4.csv": "ok", "imu7.csv": "ok", "vi7.csv": "differs"}
    details = {f.path.name: f.detail for r in reports for f in r.files}
    assert "imu4.csv has 101 rows" in details["imu4.csv"]
    assert "differs" in details["vi7.csv"] and "200 rows" in details["vi7.csv"]
    assert reports[0].failed


def test_a_missing_required_dataset_fails_and_an_optional_one_does_not(tmp_path):
    ref = [ReferenceFile("oxiod handheld", "oxiod/handheld/data1/syn/imu2.csv", "0" * 64, 1, 1, 16),
           ReferenceFile("broad", "broad/data_mat/trials.json", "0" * 64, 1, 0, None)]
    reports = {r.dataset.name: r for r in inventory.check(tmp_path, ("oxiod", "broad"), ref)}
    assert reports["oxiod handheld"].absent and reports["oxiod handheld"].failed
    assert reports["broad"].absent and not reports["broad"].failed


def test_the_ucs_file_is_checked_by_its_format_rules(tmp_path):
    ucs = tmp_path / "ucs" / "full_dataset" / "imu_adis.txt"
    assert inventory.check(tmp_path, ("ucs",), [])[0].absent
    write_ucs(ucs)
    (report,) = inventory.check(tmp_path, ("ucs",), [])
    assert [f.status for f in report.files] == ["ok"] and not report.failed
    lines = ucs.read_text().splitlines()
    ucs.write_text("\n".join(lines[:3] + [lines[3] + ",1.0"] + lines[4:]) + "\n")  # a row too long
    (report,) = inventory.check(tmp_path, ("ucs",), [])
    (f,) = report.files
    assert f.status == "malformed" and "imu_adis.txt" in f.detail and "line 4" in f.detail
    assert report.failed


def test_check_and_where_from_the_command_line(tmp_oxiod, monkeypatch, capsys):
    ref = handheld_reference(tmp_oxiod.data_dir)
    monkeypatch.setattr(inventory, "registry", lambda path=None: ref)
    args = ["--data-dir", str(tmp_oxiod.data_dir)]
    assert main(["data", "check", *args, "--experiment", "oxiod"]) == 0
    assert "8 of 8 files are the book's copies" in capsys.readouterr().out
    assert main(["data", "check", *args, "--experiment", "ucs"]) == 0
    assert "ucs (optional): absent: none of its files in" in capsys.readouterr().out
    write_ucs(tmp_oxiod.data_dir / "ucs" / "full_dataset" / "imu_adis.txt")
    assert main(["data", "check", *args, "--experiment", "ucs"]) == 0
    assert "ucs (optional): 1 of 1 files pass the loader's format rules (no reference copy)" in capsys.readouterr().out
    (tmp_oxiod.syn / "imu2.csv").unlink()
    assert main(["data", "check", *args]) == 1
    out = capsys.readouterr().out
    assert f"missing    {tmp_oxiod.syn / 'imu2.csv'}" in out and "(exit 1)" in out
    assert main(["data", "where", *args]) == 0
    out = capsys.readouterr().out
    assert f"data folder: {tmp_oxiod.data_dir}" in out and "imu2.csv, vi2.csv" in out
    assert main(["data", "check", "--data-dir", str(tmp_oxiod.data_dir / "nowhere")]) == 2
    assert "nowhere: not a directory" in capsys.readouterr().err


def test_the_registry_lists_what_the_book_reads():
    ref = inventory.registry()
    assert len(ref) == len({f.path for f in ref}) == 45
    assert {f.dataset for f in ref} == {"oxiod handheld", "oxiod trolley", "oxiod multi users", "broad"}
    assert all(len(f.sha256) == 64 and f.bytes > 0 for f in ref)
    handheld = {f.path.rsplit("/", 1)[1]: f for f in ref if f.dataset == "oxiod handheld"}
    assert handheld["imu2.csv"].rows == handheld["vi2.csv"].rows == 23446  # the data README's row count
    assert handheld["imu2.csv"].columns == 16 and handheld["vi2.csv"].columns == 9
    broad = [f for f in ref if f.path.endswith(".mat")]
    assert len(broad) == 24 and all(set(f.columns) >= {"imu_gyr", "imu_acc", "imu_mag", "opt_quat", "movement"}
                                    for f in broad)


# --- on the real copies --------------------------------------------------------------------

@pytest.fixture
def real_data() -> Path:
    env = os.environ.get("DANAE_DATA", "").strip()
    if not env or not all((Path(env) / f.path).is_file() for f in inventory.registry()):
        pytest.skip("the book's reference copies not found: set DANAE_DATA to a folder holding "
                    "oxiod/ and broad/ (see book/data.md)")
    return Path(env)


@pytest.mark.realdata
def test_the_shared_data_is_the_books_copy(real_data, capsys):
    assert main(["data", "check", "--data-dir", str(real_data)]) == 0
    out = capsys.readouterr().out
    assert "result: the data matches the book's reference copies (exit 0)" in out


@pytest.mark.realdata
def test_a_real_copy_with_a_file_removed_and_one_truncated(real_data, tmp_path, capsys):
    copy = tmp_path / "data"
    shutil.copytree(real_data, copy, symlinks=True, copy_function=os.symlink)
    syn = copy / "oxiod" / "handheld" / "data1" / "syn"
    (syn / "vi2.csv").unlink()
    imu3 = (real_data / "oxiod" / "handheld" / "data1" / "syn" / "imu3.csv").read_bytes()
    (syn / "imu3.csv").unlink()
    (syn / "imu3.csv").write_bytes(imu3[:100_000])
    mat = copy / "broad" / "data_mat" / "25_disturbed_tapping_B.mat"
    raw = mat.read_bytes()
    mat.unlink()
    mat.write_bytes(raw[:50_000])
    assert main(["data", "check", "--data-dir", str(copy)]) == 1
    out = capsys.readouterr().out
    assert f"missing    {syn / 'vi2.csv'}" in out
    assert f"malformed  {syn / 'imu3.csv'}: " in out
    assert f"malformed  {mat}: cannot be read as a MATLAB .mat file" in out
    assert "oxiod multi users (optional): 4 of 4 files are the book's copies" in out


# --- fetch against a loopback server -------------------------------------------------------

class _Files(http.server.SimpleHTTPRequestHandler):
    """Serves a folder; ``truncated.mat`` announces its whole length and sends half of it."""

    requests: list[str] = []

    def log_message(self, *args):  # quiet
        pass

    def do_GET(self):
        type(self).requests.append(self.path)
        if self.path.endswith("truncated.mat"):
            body = (Path(self.directory) / "data_mat" / "truncated.mat").read_bytes()
            self.send_response(200)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body[: len(body) // 2])
            self.wfile.flush()
            self.close_connection = True
            return
        super().do_GET()


@pytest.fixture
def server(tmp_path):
    site = tmp_path / "site"
    (site / "data_mat").mkdir(parents=True)
    handler = lambda *a, **k: _Files(*a, directory=str(site), **k)  # noqa: E731
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    _Files.requests = []
    yield site, f"http://127.0.0.1:{httpd.server_address[1]}/"
    httpd.shutdown()
    httpd.server_close()


def serve(site: Path, name: str, body: bytes, *, book_body: bytes | None = None) -> ReferenceFile:
    """Put ``body`` on the site; the reference entry has the checksum of ``book_body`` (default ``body``)."""
    import hashlib

    (site / "data_mat" / name).write_bytes(body)
    book = body if book_body is None else book_body
    return ReferenceFile("broad", f"broad/data_mat/{name}", hashlib.sha256(book).hexdigest(), len(book), 0, None)


def test_fetch_downloads_verifies_and_resumes(server, tmp_path):
    site, url = server
    ref = [serve(site, "01_a.mat", b"first trial" * 1000), serve(site, "02_b.mat", b"second" * 999)]
    data = tmp_path / "data"
    lines: list[str] = []
    written = fetch.fetch_broad(data, base_url=url, reference=ref, report=lines.append)
    assert [p.name for p in written] == ["01_a.mat", "02_b.mat"]
    assert (data / "broad" / "data_mat" / "01_a.mat").read_bytes() == b"first trial" * 1000
    assert not (data / "broad" / fetch.STAGING).exists()
    assert _Files.requests == ["/data_mat/01_a.mat", "/data_mat/02_b.mat"]
    (data / "broad" / "data_mat" / "02_b.mat").unlink()  # an interrupted first run
    assert fetch.fetch_broad(data, base_url=url, reference=ref, report=lines.append) == [data / "broad" / "data_mat" / "02_b.mat"]
    assert _Files.requests[2:] == ["/data_mat/02_b.mat"]  # the verified file was kept
    assert any(line.startswith("  kept        broad/data_mat/01_a.mat") for line in lines)


@pytest.mark.parametrize("case", ["wrong checksum", "truncated", "not on the server"])
def test_a_bad_download_is_one_line_naming_the_file_and_writes_nothing(server, tmp_path, case):
    site, url = server
    good = serve(site, "01_a.mat", b"good" * 500)
    if case == "wrong checksum":
        bad = serve(site, "02_b.mat", b"another file" * 100, book_body=b"the book's file" * 100)
    elif case == "truncated":
        bad = serve(site, "truncated.mat", b"x" * 200_000)
    else:
        bad = ReferenceFile("broad", "broad/data_mat/03_gone.mat", "0" * 64, 10, 0, None)
    data = tmp_path / "data"
    with pytest.raises(fetch.FetchError) as err:
        fetch.fetch_broad(data, base_url=url, reference=[good, bad], report=lambda line: None)
    message = str(err.value)
    assert "\n" not in message and message.startswith(bad.path) and "nothing written" in message
    assert sorted(p.name for p in (data / "broad" / "data_mat").iterdir()) == ["01_a.mat"]
    assert not (data / "broad" / fetch.STAGING).exists()


def test_fetch_from_the_command_line(server, tmp_path, monkeypatch, capsys):
    site, url = server
    ref = [serve(site, "01_a.mat", b"a" * 3000), serve(site, "02_b.mat", b"b" * 10, book_body=b"c" * 10)]
    monkeypatch.setattr(inventory, "registry", lambda path=None: ref)
    monkeypatch.setattr(fetch, "registry", lambda path=None: ref)
    data = tmp_path / "data"
    assert main(["data", "fetch", "--data-dir", str(data), "--url", url]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("python -m danae_lite data fetch: error: broad/data_mat/02_b.mat:") and "\n" not in err
    ref.pop()
    assert main(["data", "fetch", "--data-dir", str(data), "--url", url]) == 0
    out = capsys.readouterr().out
    assert "kept        broad/data_mat/01_a.mat" in out and "oxiod handheld: get it from" in out
