"""Book maintenance, not the library: re-executing the chapters and writing the pages' generated blocks.

* :mod:`tools.execute`  ``python -m tools.execute`` (``make execute``): re-executes the stale
  chapters in place and records each run inside the notebook;
* :mod:`tools.pages`    the blocks of README.md, the chapters' openings and the Performance page
  written from the stored chapters (``python -m tools.execute --pages``).

Run from the repository root; they import :mod:`danae_lite` and are not part of it.
"""
