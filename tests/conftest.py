"""Shared fixtures and writers: the real OxIOD folder (skipped when absent), synthetic OxIOD and UCS files."""
from __future__ import annotations

import os
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

OXIOD_KS = (2, 3, 4, 7)
SYNTH_ROWS = 200
WITHOUT_DATA = "test_chapters_without_data.py"
"""The file that runs every chapter a second time, without data."""


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Run the second run of the chapters, without data (:data:`WITHOUT_DATA`, the longest
    file), first; then the chapters, the last chapter first (later chapters build on the earlier
    ones and cost the most); then the unit tests in their usual order.

    ``make test`` hands whole files to its workers in this order (``--dist loadfile
    --no-loadscope-reorder``: xdist would otherwise put the files with the most tests first), so
    one worker runs the chapters without data while the other runs them with data, and the short
    unit-test files fill the gaps, instead of a long file starting last on one worker while the
    other idles.
    """
    chapters = sorted((i for i in items if i.path.suffix == ".ipynb"), key=lambda i: i.path.name, reverse=True)
    without_data = [i for i in items if i.path.name == WITHOUT_DATA]
    rest = [i for i in items if i.path.suffix != ".ipynb" and i.path.name != WITHOUT_DATA]
    items[:] = without_data + chapters + rest


def synthetic_oxiod(n: int = SYNTH_ROWS, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows of an OxIOD-format (imu, vi) pair built from a known rotation, plus its (N, 3) Euler.

    The Vicon body rotates by ``euler`` (roll, pitch, yaw; intrinsic ZYX). The phone frame is
    the Vicon frame turned 180° about z (x, y negated) and iOS gravity points down, so the
    phone-frame gravity is ``-(ux, uy, uz) * (-1, -1, 1)`` with ``u = R.T @ [0, 0, 1]``.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0
    euler = np.c_[-0.4 + 0.1 * np.sin(2.0 * np.pi * 0.5 * t + seed),
                  0.15 * np.sin(2.0 * np.pi * 0.3 * t),
                  -1.0 + 0.5 * t]
    rot = Rotation.from_euler("ZYX", euler[:, ::-1])
    up = rot.inv().apply([0.0, 0.0, 1.0])
    gravity = -up * np.array([-1.0, -1.0, 1.0])
    user_acc = 0.05 * np.c_[np.sin(7.0 * t), np.cos(5.0 * t), np.sin(3.0 * t)]
    gyro = rng.normal(0.0, 0.1, (n, 3))
    mag = rng.normal([20.0, -5.0, -40.0], 0.5, (n, 3))
    phone_euler = euler + [0.0, 0.0, np.pi]
    imu = np.c_[1.4955e11 + t, phone_euler, gyro, gravity, user_acc, mag]
    vi = np.c_[1.4955e11 + t, 55308 + np.arange(n), rng.normal(0.0, 1.0, (n, 3)), rot.as_quat()]
    return imu, vi, euler


def write_rows(path: Path, rows: np.ndarray) -> None:
    """Write rows as comma-separated values without header, exactly representable (%.17g)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, rows, fmt="%.17g", delimiter=",")


# --- UCS files in the export layout ----------------------------------------------------

UCS_HEADER = (
    "%time,field.header.seq,field.header.stamp,field.roll,field.pitch,field.yaw,field.qx,field.qy,field.qz,"
    "field.qw,field.temp,field.mx,field.my,field.mz,field.ax,field.ay,field.az,field.gx,field.gy,field.gz,"
    "field.bx,field.by,field.bz").split(",")
"""Header row of the UCS ``imu_adis.txt`` export (rostopic echo -p of cirs_girona_cala_viuda/Imu)."""
G = 9.80665
T0 = 1_437_742_140_000_000_000  # ns
FIELD_UT = 48.0 * np.array([np.cos(np.radians(60.0)), 0.0, -np.sin(np.radians(60.0))])


def edit_line(path: Path, line: int, text: str | None) -> None:
    """Replace (or delete, with None) the 1-based ``line`` of a text file."""
    lines = path.read_text().splitlines()
    if text is None:
        del lines[line - 1]
    else:
        lines[line - 1] = text
    path.write_text("\n".join(lines) + "\n")


def edit_cell(path: Path, line: int, col: int, value: str) -> None:
    """Replace the cell at 1-based ``line`` and 1-based ``col`` of a CSV file."""
    fields = path.read_text().splitlines()[line - 1].split(",")
    fields[col - 1] = value
    edit_line(path, line, ",".join(fields))


def ucs_signals(n: int = 300, fs: float = 10.2, seed: int = 0) -> dict[str, np.ndarray]:
    """Signals of a slowly rolling/pitching AUV in the file's units (acc m/s², mag gauss)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    euler = np.c_[0.05 * np.sin(0.3 * t), 0.1 * np.sin(0.2 * t + 1.0), 0.02 * t]  # roll, pitch, yaw
    rot = Rotation.from_euler("ZYX", euler[:, ::-1])
    up = rot.inv().apply([0.0, 0.0, 1.0])
    stamps = T0 + np.round(t * 1e9 + rng.uniform(-2e6, 2e6, n)).astype(np.int64)
    return {
        "%time": stamps,
        "field.header.seq": np.arange(n),
        "field.header.stamp": stamps - 1_000_000,
        "field.roll": euler[:, 0], "field.pitch": euler[:, 1], "field.yaw": euler[:, 2],
        "q": rot.as_quat(),
        "field.temp": 20.0 + 0.01 * t,
        "m": rot.inv().apply(FIELD_UT) / 100.0,
        "a": G * up + rng.normal(0.0, 0.02, (n, 3)),
        "g": rng.normal(0.0, 0.01, (n, 3)),
        "b": np.tile([1e-4, -2e-4, 3e-4], (n, 1)),
        "up": up,
    }


def columns(sig: dict[str, np.ndarray]) -> dict[str, list[str]]:
    """Text of every header column."""
    vec = {"q": "field.q", "m": "field.m", "a": "field.a", "g": "field.g", "b": "field.b"}
    out: dict[str, list[str]] = {}
    for key, value in sig.items():
        if key in vec:
            axes = "xyzw" if key == "q" else "xyz"
            for i, ax in enumerate(axes):
                out[vec[key] + ax] = [repr(float(v)) for v in value[:, i]]
        elif key != "up":
            out[key] = [str(v) if value.dtype.kind == "i" else repr(float(v)) for v in value]
    return out


def _norm(name: str) -> str:
    return name.strip().lstrip("%").strip()


def write_ucs(path: Path, sig: dict[str, np.ndarray] | None = None, header: list[str] | None = None,
              extra: dict[str, list[str]] | None = None) -> Path:
    """Write an ``imu_adis.txt`` in the export layout: a header row, then comma-separated rows.

    ``header`` may rename (whitespace, ``%``) or reorder the columns; ``extra`` adds columns
    (name -> cell texts), which must also be named in ``header``.
    """
    cols = {_norm(k): v for k, v in (columns(sig if sig is not None else ucs_signals()) | (extra or {})).items()}
    names = list(header if header is not None else UCS_HEADER)
    n = len(cols["time"])
    rows = (",".join(cols[_norm(h)][i] for h in names) for i in range(n))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(",".join(names) + "\n" + "\n".join(rows) + "\n")
    return path


@pytest.fixture(scope="session")
def oxiod_dir() -> Path:
    """The real OxIOD root ``$DANAE_DATA/oxiod`` (skips the test when it is absent)."""
    env = os.environ.get("DANAE_DATA", "").strip()
    root = Path(env) / "oxiod" if env else None
    if root is None or not all((root / "handheld" / "data1" / "syn" / f"{p}{k}.csv").is_file()
                               for k in OXIOD_KS for p in ("imu", "vi")):
        pytest.skip("real OxIOD not found: set DANAE_DATA to a folder holding "
                    "oxiod/handheld/data1/syn/imuK.csv + viK.csv")
    return root


@pytest.fixture
def tmp_oxiod(tmp_path: Path) -> SimpleNamespace:
    """A synthetic OxIOD tree ``<tmp>/oxiod/handheld/data1/syn/{imu,vi}{2,3,4,7}.csv`` (200 rows each).

    Returns a namespace with ``data_dir`` (the folder holding ``oxiod/``), ``root`` (the OxIOD
    root), ``syn`` (the folder of the files), and per K the written ``imu[K]``, ``vi[K]`` rows
    and the generating ``euler[K]`` (roll, pitch, yaw) [rad].
    """
    root = tmp_path / "oxiod"
    syn = root / "handheld" / "data1" / "syn"
    out = SimpleNamespace(data_dir=tmp_path, root=root, syn=syn, imu={}, vi={}, euler={})
    for k in OXIOD_KS:
        imu, vi, euler = synthetic_oxiod(seed=k)
        write_rows(syn / f"imu{k}.csv", imu)
        write_rows(syn / f"vi{k}.csv", vi)
        out.imu[k], out.vi[k], out.euler[k] = imu, vi, euler
    return out


@pytest.fixture
def one_torch_thread():
    """Small networks: one torch thread is fastest, and immune to oversubscribed cores."""
    import torch

    old = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(old)


def assert_close_scaled(actual, desired, rtol: float) -> None:
    """``assert_allclose`` whose absolute tolerance scales with the array it checks.

    Two correct computations of a matrix (another summation order, another thread count,
    another algorithm) agree on its large entries to ``rtol`` but leave rounding noise of
    order ``rtol * max|desired|`` in the entries that should be zero; a fixed ``atol`` such as
    1e-12 then fails on the size of the matrix, not on an error. The absolute tolerance here
    is ``rtol * max|desired|``.
    """
    desired = np.asarray(desired, dtype=float)
    scale = float(np.abs(desired).max()) if desired.size else 0.0
    np.testing.assert_allclose(actual, desired, rtol=rtol, atol=rtol * scale)


def stored_networks(folder: Path) -> list[tuple[str, int, str]]:
    """(tag, seed, key) of each network kept in a cache folder (the items of its joblib store,
    danae_lite.danae.networks.NetworkCache), sorted."""
    import joblib

    found = []
    for f in Path(folder).glob("networks/*/output.pkl"):
        meta = joblib.load(f)["metadata"]
        found.append((str(meta["tag"]), int(meta["seed"]), f.parent.name))
    return sorted(found)


def network_items(folder: Path) -> list[Path]:
    """The stored files of the networks kept in a cache folder, sorted."""
    return sorted(Path(folder).glob("networks/*/output.pkl"))
