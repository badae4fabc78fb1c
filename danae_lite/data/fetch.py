"""Download what is public: the BROAD trials the book uses (CC BY 4.0), with pooch.

Exactly the BROAD files of the book's reference copy (:func:`danae_lite.data.inventory.registry`)
are fetched, each from its own URL pinned to one commit of the benchmark's repository
(:data:`BROAD_COMMIT`), and checked against the book's SHA-256 by pooch. Each download goes
to a staging folder beside the data (``broad/.fetch-staging``) and is renamed into
``broad/data_mat`` only once verified, so nothing partial reaches the data folder; a file
already there with the book's checksum is kept, so a second run resumes where the first
stopped. OxIOD and UCS are distributed by their authors on request: :func:`manual_steps`
says where to get them and where to put them.
"""
from __future__ import annotations

import os
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path

from .inventory import DATASETS, ReferenceFile, registry, sha256

BROAD_COMMIT = "afbaa4d75c4cd7c8ca76b8145b1812312d87fb7f"
"""The commit of github.com/dlaidig/broad whose ``data_mat/`` files the book read."""
BROAD_URL = f"https://raw.githubusercontent.com/dlaidig/broad/{BROAD_COMMIT}/"
"""Base URL of the pinned files: a file's URL is this plus its path after ``broad/``."""
STAGING = ".fetch-staging"
"""Staging folder, inside ``<data dir>/broad``."""


class FetchError(Exception):
    """A download that failed or did not match the book's copy; the message is one line naming the file."""


def broad_files(reference: Sequence[ReferenceFile] | None = None) -> list[ReferenceFile]:
    """The BROAD files of the book's reference copy."""
    return [f for f in (registry() if reference is None else reference) if f.dataset == "broad"]


def _download(url: str, ref: ReferenceFile, staging: Path) -> Path:
    """One file into ``staging`` through pooch, its SHA-256 checked; FetchError otherwise."""
    import pooch
    import requests

    name = Path(ref.path).name
    try:
        return Path(pooch.retrieve(url, known_hash=f"sha256:{ref.sha256}", fname=name, path=staging,
                                   progressbar=False))
    except ValueError as err:
        if "hash" not in str(err).lower():
            raise
        raise FetchError(f"{ref.path}: the download from {url} does not match the book's copy "
                         f"(SHA-256 differs; expected {ref.bytes} bytes, sha256 {ref.sha256[:16]}...); "
                         "nothing written") from None
    except requests.RequestException as err:
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise FetchError(f"{ref.path}: download from {url} failed ({reason}); nothing written") from None


def fetch_broad(data_dir: Path, *, base_url: str = BROAD_URL,
                reference: Sequence[ReferenceFile] | None = None,
                report: Callable[[str], None] = print) -> list[Path]:
    """Download the book's BROAD files that ``data_dir/broad/data_mat`` lacks or holds with
    another checksum; return the paths written. ``report`` gets one line per file."""
    import pooch

    pooch.get_logger().setLevel("WARNING")  # one line per file is ours to print
    files = broad_files(reference)
    staging = data_dir / "broad" / STAGING
    written = []
    try:
        for ref in files:
            target = data_dir / ref.path
            if target.is_file() and target.stat().st_size == ref.bytes and sha256(target) == ref.sha256:
                report(f"  kept        {ref.path} (the book's copy)")
                continue
            url = base_url.rstrip("/") + "/" + ref.path.split("/", 1)[1]
            staging.mkdir(parents=True, exist_ok=True)
            staged = _download(url, ref, staging)
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(staged, target)  # the same file system: whole or not at all
            written.append(target)
            report(f"  downloaded  {ref.path} ({ref.bytes / 1e6:.1f} MB, SHA-256 verified)")
    finally:  # what a failed download left there is partial; every verified file is in place
        shutil.rmtree(staging, ignore_errors=True)
    return written


def manual_steps(data_dir: Path) -> list[str]:
    """Where to get the datasets that cannot be downloaded here, and where they go."""
    out = []
    for ds in DATASETS:
        if ds.name == "broad":
            continue
        out.append(f"  {ds.name}: get it from {ds.source} and put its files in {data_dir / ds.folder}")
    return out
