"""Time the project's CI from a fresh clone and record it for the README and the Performance page.

    python benchmarks/ci_times.py [--clone DIR] [--json FILE]

Clones the repository's committed HEAD into ``DIR`` (default: a new folder beside the
repository, so that ``.ci/run`` finds ``../shared/data`` as it does in CI), runs ``.ci/run``
there with ``CI=true`` and no standard input, and writes what it printed to ``DIR/ci.log`` and
its times to ``FILE`` (default ``benchmarks/results/commands.json``): the whole run, ``make test``
(which creates ``.venv`` first) and ``make book`` in seconds, pytest's counts, the commit and the
machine. ``tools.pages.timings_markdown`` turns that record into the timings table; run
``python -m tools.execute --pages`` afterwards. Exits with ``.ci/run``'s status, writing no
record when it failed.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from tools import conditions  # noqa: E402  (run as a script from anywhere)


def cpu_label() -> str:
    """'<model>, <n> cores, <AVX-512|AVX2>' from /proc/cpuinfo."""
    try:
        cpuinfo = Path("/proc/cpuinfo").read_text(encoding="utf-8", errors="replace")
    except OSError:
        cpuinfo = ""
    flags = next((set(value.split()) for key, _, value in (line.partition(":") for line in cpuinfo.splitlines())
                  if key.strip() == "flags"), set())
    isa = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else "neither AVX2 nor AVX-512"
    return f"{conditions.cpu_model(cpuinfo)}, {os.cpu_count()} cores, {isa}"


def parse_log(text: str) -> dict[str, int]:
    """The seconds of ``make test`` and ``make book`` that ``.ci/run`` prints and pytest's counts;
    ValueError naming what the log lacks."""
    found: dict[str, int] = {}
    for key, pattern in (("make_test_s", r"^make test: (\d+) s$"), ("make_book_s", r"^make book: (\d+) s$"),
                         ("tests_passed", r"(\d+) passed"), ("tests_skipped", r"(\d+) skipped")):
        matches = re.findall(pattern, text, flags=re.M)
        if matches:
            found[key] = int(matches[-1])
        elif key == "tests_skipped":
            found[key] = 0
        else:
            raise ValueError(f"the .ci/run log has no line matching {pattern!r}")
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--clone", type=Path, default=ROOT.parent / f"{ROOT.name}-ci-clone",
                        help="new folder for the fresh clone (must not exist)")
    parser.add_argument("--json", type=Path, default=ROOT / "benchmarks" / "results" / "commands.json",
                        help="where to write the record")
    args = parser.parse_args(argv)
    if args.clone.exists():
        parser.error(f"{args.clone} exists: name a new folder with --clone")
    subprocess.run(["git", "clone", "--quiet", str(ROOT), str(args.clone)], check=True)
    commit = subprocess.run(["git", "-C", str(args.clone), "rev-parse", "--short", "HEAD"], check=True,
                            capture_output=True, text=True).stdout.strip()
    log_path = args.clone / "ci.log"
    start = time.perf_counter()
    with log_path.open("w", encoding="utf-8") as log:
        rc = subprocess.run([".ci/run"], cwd=args.clone, env={**os.environ, "CI": "true"},
                            stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT).returncode
    seconds = time.perf_counter() - start
    if rc != 0:
        print(f".ci/run failed with status {rc}: see {log_path}", file=sys.stderr)
        return rc
    record = {"date": _dt.date.today().isoformat(), "commit": commit, "machine": cpu_label(),
              "ci_run_s": round(seconds), **parse_log(log_path.read_text(encoding="utf-8"))}
    args.json.write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(record, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
