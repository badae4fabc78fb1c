import pytest

from danae_lite.config import data_dir, fast_mode


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
