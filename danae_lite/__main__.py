"""``python -m danae_lite``: the command line (see :mod:`danae_lite.cli`)."""
from .cli import main

if __name__ == "__main__":
    raise SystemExit(main())
