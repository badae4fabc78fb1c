import re
from pathlib import Path

import pytest

from danae_lite.runtime import data_dir, fast_mode


def test_fast_mode_values(monkeypatch):
    monkeypatch.setenv("DANAE_FAST", "1")
    assert fast_mode() is True
    monkeypatch.setenv("DANAE_FAST", "no")
    assert fast_mode() is False
    assert fast_mode(True) is True
    monkeypatch.setenv("DANAE_FAST", "maybe")
    with pytest.raises(ValueError, match="DANAE_FAST='maybe'"):
        fast_mode()


def test_data_dir(monkeypatch, tmp_path):
    monkeypatch.delenv("DANAE_DATA", raising=False)
    assert data_dir() is None
    monkeypatch.setenv("DANAE_DATA", str(tmp_path))
    assert data_dir() == tmp_path.resolve()
    assert data_dir(tmp_path) == tmp_path.resolve()
    with pytest.raises(FileNotFoundError, match="not a directory"):
        data_dir(tmp_path / "missing")
    monkeypatch.setenv("DANAE_DATA", str(tmp_path / "nope"))
    with pytest.raises(FileNotFoundError, match=r"\$DANAE_DATA"):
        data_dir()


def test_cache_defaults_to_the_user_cache_folder_and_can_be_turned_off(monkeypatch, tmp_path):
    from danae_lite.runtime import RunSettings, cache_dir

    monkeypatch.delenv("DANAE_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))  # platformdirs' Linux convention
    assert cache_dir() == (tmp_path / "xdg" / "danae_lite").resolve()
    monkeypatch.setenv("DANAE_CACHE", str(tmp_path / "mine"))
    assert cache_dir() == (tmp_path / "mine").resolve()
    for off in ("off", "none", "OFF"):
        monkeypatch.setenv("DANAE_CACHE", off)
        assert cache_dir() is None and RunSettings.from_env().cache is None
    assert cache_dir(tmp_path) == tmp_path.resolve()  # an explicit folder wins over the variable


def test_full_and_fast_networks_are_kept_apart_each_capped(monkeypatch, tmp_path):
    from danae_lite.runtime import DEFAULT_CACHE_GB, RunSettings
    from tools.execute import kernel_environment

    monkeypatch.setenv("DANAE_CACHE", str(tmp_path))
    monkeypatch.delenv("DANAE_CACHE_GB", raising=False)
    full, fast = RunSettings.from_env(fast=False).cache, RunSettings.from_env(fast=True).cache
    assert (full.folder, fast.folder) == (tmp_path.resolve() / "full", tmp_path.resolve() / "fast")
    assert full.max_bytes == fast.max_bytes == int(DEFAULT_CACHE_GB * 1e9)
    monkeypatch.setenv("DANAE_CACHE_GB", "0.5")
    assert RunSettings.from_env().cache.max_bytes == 500_000_000
    # a chapter's kernel reads back the same root and cap (not the sub-folder: it picks its own)
    env = kernel_environment(data_dir=None, cache=tmp_path, fast=True, n_jobs=1, max_gb=0.5, base={})
    monkeypatch.setattr("os.environ", env)
    assert RunSettings.from_env().cache == fast.__class__(tmp_path.resolve() / "fast", 500_000_000)
    assert kernel_environment(data_dir=None, cache=None, fast=False, n_jobs=1, base={})["DANAE_CACHE"] == "off"


@pytest.mark.parametrize("bad", ["0", "-1", "lots", "inf"])
def test_cache_cap_must_be_a_positive_size(monkeypatch, bad):
    from danae_lite.runtime import cache_gb

    monkeypatch.setenv("DANAE_CACHE_GB", bad)
    with pytest.raises(ValueError, match=f"DANAE_CACHE_GB='{bad}'"):
        cache_gb()



def test_fast_mode_caps_steps_and_epochs_only():
    from danae_lite.runtime import FAST_EPOCHS, FAST_MAX_STEPS, RunSettings
    from danae_lite.danae.train_types import TrainConfig

    base = TrainConfig(epochs=5)
    full = RunSettings(fast=False).train_config(base)
    assert (full.epochs, full.max_steps, full.val_every) == (5, None, None)
    fast = RunSettings(fast=True).train_config(base)
    # validation keeps its schedule (ten checks per epoch): chapter 3's hand-written loop repeats it
    assert (fast.epochs, fast.max_steps, fast.val_every) == (FAST_EPOCHS, FAST_MAX_STEPS, None)
    assert RunSettings(fast=True).train_config(TrainConfig(max_steps=3)).max_steps == 3
    assert RunSettings(fast=True).train_config(TrainConfig(max_steps=400)).max_steps == FAST_MAX_STEPS


def test_the_pages_and_chapters_state_the_fast_mode_cap():
    import json

    from danae_lite.runtime import FAST_MAX_STEPS

    root = Path(__file__).resolve().parents[1]
    texts = {page: (root / page).read_text(encoding="utf-8") for page in ("README.md", "book/performance.md")}
    for path in sorted((root / "notebooks").glob("0*.ipynb")):
        cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
        texts[path.name] = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "markdown")
    stated = {where: re.findall(r"at most (\d+) optimiser steps", " ".join(text.split()))
              for where, text in texts.items()}
    assert stated["README.md"] and stated["book/performance.md"] and stated["04_reproduce_paper.ipynb"]
    wrong = {where: found for where, found in stated.items() if set(found) - {str(FAST_MAX_STEPS)}}
    assert not wrong, f"fast mode caps each network at {FAST_MAX_STEPS} steps: {wrong}"
