"""The command line answers at once: ``--help`` of every command loads no torch and no pandas
(checked in ``sys.modules`` of a fresh interpreter, not by the clock); ``--version``; ``--no-fast``
beside ``--fast``; the static table of method names equals the leaderboard's."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from danae_lite import __version__, cli
from danae_lite.commands import method_names
from danae_lite.research import baselines
from danae_lite.runtime import FAST_ENV, RunSettings

HELPS = [["--help"], ["reproduce", "--help"], ["leaderboard", "--help"], ["data", "--help"],
         ["data", "where", "--help"], ["data", "check", "--help"], ["data", "fetch", "--help"], ["--version"]]
PROBE = """
import contextlib, io, json, sys
from danae_lite.cli import main
with contextlib.redirect_stdout(io.StringIO()) as out:
    status = main(sys.argv[1:])
print(json.dumps({"status": status, "heavy": [m for m in ("torch", "pandas") if m in sys.modules],
                  "out": out.getvalue()}))
"""


@pytest.mark.parametrize("argv", HELPS, ids=" ".join)
def test_help_loads_no_torch_or_pandas(argv):
    run = subprocess.run([sys.executable, "-c", PROBE, *argv], capture_output=True, text=True, check=True)
    got = json.loads(run.stdout)
    assert got["status"] == 0 and got["heavy"] == []
    assert got["out"].strip()


def test_the_torch_probe_sees_what_a_command_loads():
    code = PROBE.replace("status = main(sys.argv[1:])", "status = 0; import danae_lite.research.baselines")
    got = json.loads(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                    check=True).stdout)
    assert got["heavy"] == ["torch", "pandas"]


def test_help_names_the_data_check_and_the_books_re_execution(capsys):
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    assert "python -m danae_lite data check" in out and "python -m tools.execute" in out


def test_version(capsys):
    assert cli.main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"python -m danae_lite (danae_lite) {__version__}"


@pytest.mark.parametrize("command", ["reproduce", "leaderboard"])
def test_no_fast_overrides_the_environment(command, monkeypatch):
    parser = cli.build_parser()
    assert parser.parse_args([command, "--fast"]).fast is True
    assert parser.parse_args([command]).fast is None
    args = parser.parse_args([command, "--no-fast"])
    assert args.fast is False
    monkeypatch.setenv(FAST_ENV, "1")
    assert RunSettings.from_env(fast=args.fast).fast is False
    assert RunSettings.from_env(fast=None).fast is True


def test_the_static_method_table_is_the_leaderboards():
    assert method_names.METHOD_NAMES == baselines.METHODS
    assert method_names.DENOISER_FAMILIES == baselines.DENOISER_FAMILIES
    names = [*baselines.METHODS, "danae-res[vqf]", "danae-safe[paper_kf]", "danae-res[danae]",
             "danae-safe[danae-res[vqf]]", "danae-res[]", "danae-res[nope]", "nope", "DANAE", ""]
    assert [method_names.is_method_name(n) for n in names] == [baselines.is_method_name(n) for n in names]
