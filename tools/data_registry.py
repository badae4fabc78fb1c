"""Write the registry of the book's reference copies, ``danae_lite/data/reference_copies.json``:
every data file the stored outputs read, with its SHA-256, size, rows and columns
(:mod:`danae_lite.data.inventory`). Checksums and shapes only: no data.

    python -m tools.data_registry DATA_DIR

``DATA_DIR`` is the folder the book was executed on (``DANAE_DATA``). Run it when the book's
outputs are re-executed on another copy of the data.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from danae_lite.data import inventory
from danae_lite.data.oxiod_motions import OXIOD_MOTIONS

OUT = Path(inventory.__file__).with_name(inventory.REGISTRY_NAME)


def reference_paths(root: Path) -> list[tuple[str, str]]:
    """``(dataset, path relative to root)`` of every file the book reads, in registry order."""
    out = []
    for motion, (setting, folder, ks) in OXIOD_MOTIONS.items():
        for k in ks:
            for stem in ("imu", "vi"):
                out.append((f"oxiod {motion}", f"oxiod/{setting}/{folder}/syn/{stem}{k}.csv"))
    broad = root / "broad" / "data_mat"
    out += [("broad", f"broad/data_mat/{p.name}") for p in sorted(broad.glob("*.mat"))]
    out.append(("broad", "broad/data_mat/trials.json"))
    return out


def entry(root: Path, dataset: str, rel: str) -> dict[str, object]:
    path = root / rel
    rows, columns = inventory.shape_of(path)
    return {"dataset": dataset, "path": rel, "sha256": inventory.sha256(path),
            "bytes": path.stat().st_size, "rows": rows, "columns": columns}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.data_registry", description=__doc__.split("\n\n")[0])
    parser.add_argument("data_dir", type=Path)
    args = parser.parse_args(argv)
    files = [entry(args.data_dir, ds, rel) for ds, rel in reference_paths(args.data_dir)]
    about = ("The book's reference copies: SHA-256, size [bytes], rows and columns of every data file "
             "its stored outputs read (python -m tools.data_registry). Checksums, not data.")
    rows = ",\n".join(f"  {json.dumps(f)}" for f in files)  # one file per line
    OUT.write_text(f'{{\n "about": {json.dumps(about)},\n "files": [\n{rows}\n ]\n}}\n', encoding="utf-8")
    print(f"{OUT}: {len(files)} files", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
