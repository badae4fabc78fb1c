"""``python -m danae_lite data where|check|fetch``: the data folder in use, what it holds against
the book's reference copies (:mod:`danae_lite.data.inventory`), and the public datasets
downloaded into it (:mod:`danae_lite.data.fetch`).

Exit status of ``check``: 0 when every dataset present is the book's copy and the required one
is there (an optional dataset may be absent); 1 when a file the chapters need is missing or
malformed, or a file's checksum differs from the book's (the numbers will differ from the
book's). ``fetch``: 0, or 1 with a one-line error naming the file.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..data import inventory
from ..runtime import DATA_ENV, data_env
from .data_flags import UsageError
from .prepare import PROG


def data_folder(args: argparse.Namespace, *, must_exist: bool = True) -> tuple[Path | None, str]:
    """The data folder asked for (``--data-dir``, else ``$DANAE_DATA``) and where the setting came from."""
    given, origin = args.data_dir, "--data-dir"
    if given is None:
        given, origin = data_env(), f"${DATA_ENV}"
    if given is None:
        return None, f"neither --data-dir nor ${DATA_ENV} is set"
    path = Path(given).expanduser().resolve()
    if must_exist and not path.is_dir():
        raise UsageError(f"{origin} {path}: not a directory")
    return path, origin


def where(args: argparse.Namespace) -> int:
    root, origin = data_folder(args)
    if root is None:
        print(f"data folder: none ({origin}): every chapter and command runs on the simulator")
        root_text = f"${DATA_ENV}"
    else:
        print(f"data folder: {root} (from {origin})")
        root_text = str(root)
    names = {}
    for ref in inventory.registry():
        names.setdefault(ref.dataset, []).append(Path(ref.path).name)
    for ds in inventory.DATASETS:
        folder = f"{root_text}/{ds.folder}"
        here = "" if root is None else ("  [present]" if (root / ds.folder).is_dir() else "  [absent]")
        files = names.get(ds.name, ["imu_adis.txt"])
        shown = ", ".join(files) if len(files) <= 8 else f"{len(files)} files ({files[0]} ... {files[-1]})"
        need = "required" if ds.required else "optional"
        print(f"{ds.name} ({need}): {folder}/{here}\n    reads {shown}\n    without it: {ds.when_absent}")
    return 0


def check(args: argparse.Namespace) -> int:
    root, origin = data_folder(args)
    if root is None:
        print(f"data folder: none ({origin}); nothing to check: the simulator stands in", file=sys.stderr)
        return 1
    print(f"data folder: {root} (from {origin})")
    reports = inventory.check(root, tuple(args.experiment or inventory.EXPERIMENTS))
    for rep in reports:
        ds = rep.dataset
        need = "required" if ds.required else "optional"
        if rep.absent:
            verdict = "MISSING" if ds.required else "absent"
            print(f"{ds.name} ({need}): {verdict}: none of its files in {root / ds.folder}; {ds.when_absent}; "
                  f"get it from {ds.source}")
            continue
        ok = sum(f.status == "ok" for f in rep.files)
        kind = "are the book's copies" if ds.reference_copy else "pass the loader's format rules (no reference copy)"
        print(f"{ds.name} ({need}): {ok} of {len(rep.files)} files {kind}")
        for f in rep.files:
            text = f.detail.removeprefix(f"{f.path}: ").removeprefix(f"{f.path} ")  # the path is on the line
            detail = f": {text}" if f.detail and f.status != "ok" else ""
            print(f"  {f.status:<9}  {f.path}{detail}")
    failed = [r for r in reports if r.failed]
    differs = any(f.status == "differs" for r in reports for f in r.files)
    if not failed:
        print("result: the data matches the book's reference copies (exit 0)")
        return 0
    names = ", ".join(r.dataset.name for r in failed)
    tail = "; files that differ: the numbers will differ from the book's" if differs else ""
    print(f"result: {names}: missing, malformed or different files{tail} (exit 1)")
    return 1


def fetch(args: argparse.Namespace) -> int:
    from ..data.fetch import FetchError, fetch_broad, manual_steps

    root, origin = data_folder(args, must_exist=False)
    if root is None:
        raise UsageError(f"fetch needs a data folder: --data-dir DIR or ${DATA_ENV} ({origin})")
    count = sum(ref.dataset == "broad" for ref in inventory.registry())
    print(f"data folder: {root} (from {origin})\nbroad: the book's {count} files from {args.url}")
    try:
        written = fetch_broad(root, base_url=args.url)
    except FetchError as err:
        print(f"{PROG} data fetch: error: {err}", file=sys.stderr)
        return 1
    print(f"broad: {len(written)} file(s) downloaded; the rest were already the book's copies")
    print("not downloadable here (distributed by their authors):")
    print("\n".join(manual_steps(root)))
    print(f"then: {PROG} data check")
    return 0


def run(args: argparse.Namespace) -> int:
    """Run ``data where|check|fetch``."""
    return {"where": where, "check": check, "fetch": fetch}[args.data_command](args)
