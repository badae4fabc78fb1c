"""The Recording type validates its arrays and derives Euler angles with SciPy."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from danae_lite.data.recording import DataError, Recording


def make(n=30, **over):
    kw = dict(
        name="t",
        source="test",
        fs=100.0,
        gyro=np.zeros((n, 3)),
        acc=np.tile([0.0, 0.0, 1.0], (n, 1)),
        mag=np.tile([20.0, 0.0, -40.0], (n, 1)),
        quat=np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)),
    )
    kw.update(over)
    return Recording(**kw)


def test_basic_properties():
    r = make(250)
    assert len(r) == 250 and r.dt == 0.01 and r.duration == 2.5
    np.testing.assert_allclose(r.time[:3], [0.0, 0.01, 0.02])
    np.testing.assert_allclose(r.euler, 0.0)


def test_euler_from_scipy():
    rot = Rotation.from_euler("ZYX", [0.4, -0.2, 0.1])  # yaw, pitch, roll
    r = make(5, quat=np.tile(rot.as_quat(), (5, 1)))
    np.testing.assert_allclose(r.euler[0], [0.1, -0.2, 0.4], atol=1e-12)


def test_arrays_are_read_only():
    r = make()
    with pytest.raises(ValueError):
        r.gyro[0, 0] = 1.0


@pytest.mark.parametrize(
    "field, value, msg",
    [
        ("gyro", np.zeros((30, 2)), r"gyro must have shape \(N, 3\)"),
        ("mag", np.zeros((29, 3)), "mag has 29 rows but gyro has 30"),
        ("quat", np.zeros((30, 4)), "quat row 0 is zero"),
        ("fs", 0.0, "sample rate fs must be a positive"),
    ],
)
def test_bad_arrays(field, value, msg):
    with pytest.raises(DataError, match=msg):
        make(**{field: value})


def test_nan_is_named_by_row_and_column():
    acc = np.tile([0.0, 0.0, 1.0], (30, 1))
    acc[7, 2] = np.nan
    with pytest.raises(DataError, match=r"acc\[7, 2\] is nan"):
        make(acc=acc)


def test_slice_keeps_offset():
    r = make(100).slice(10, 40)
    assert len(r) == 30 and r.meta["offset"] == 10
    with pytest.raises(DataError, match="empty"):
        make(10).slice(20, 30)


def test_slice_cuts_per_sample_meta():
    r = make(50, meta={"gravity": np.arange(150.0).reshape(50, 3), "rate": 3.0})
    s = r.slice(5, 15)
    np.testing.assert_array_equal(s.meta["gravity"], np.arange(150.0).reshape(50, 3)[5:15])
    assert s.meta["rate"] == 3.0
    assert s.slice(2, 4).meta["offset"] == 7
