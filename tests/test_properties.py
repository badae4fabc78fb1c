"""Property-based tests (hypothesis) of the conventions, windows, KF and loaders.

Every property is checked against an independent reference: scipy's ``Rotation`` or closed
forms for the angles, plain slicing for the windows, a first-order error bound for the KF, and
a small line-by-line parser written here for the loaders. All runs are deterministic
(``derandomize=True``) and short (at most 100 examples each).
"""
from __future__ import annotations

import math
import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import event, example, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from conftest import synthetic_oxiod, ucs_signals, write_rows, write_ucs
from danae_lite.data import oxiod, ucs
from danae_lite.angles import angle_diff, euler_to_quat, quat_to_euler, wrap
from danae_lite.kalman.filter import kalman_filter
from danae_lite.kalman.gains import gain_sequence
from danae_lite.kalman.model import KFConfig
from danae_lite.data.recording import DataError
from danae_lite.danae.windows import (sliding_windows, stitch_overlap_average,
                                      stitch_tiles, tile_windows)

PI = math.pi
TAU = 2.0 * math.pi


def props(n: int = 60) -> settings:
    """Fast, reproducible hypothesis settings (no example database, no deadline)."""
    return settings(max_examples=n, deadline=None, derandomize=True, database=None)


def ang_dist(a: np.ndarray | float, b: np.ndarray | float) -> np.ndarray:
    """|a - b| modulo 2 pi, in [0, pi], computed exactly with IEEE remainder (not with wrap)."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    return np.abs(np.vectorize(math.remainder)(d, TAU))


def ulp(x: float) -> float:
    return float(np.spacing(abs(x)))


# ======================================================================================
# 1. Euler <-> quaternion against scipy (intrinsic ZYX, arrays in (roll, pitch, yaw))
# ======================================================================================
full_angle = st.floats(-PI, PI)  # both ends included: the seam is part of the property
safe_pitch = st.floats(-PI / 2 + 0.05, PI / 2 - 0.05)  # away from gimbal lock


def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@props(100)
@given(full_angle, safe_pitch, full_angle)
@example(PI, 0.3, PI).via("the +pi seam")
@example(-PI, -0.3, -PI).via("the -pi seam")
@example(0.0, 0.0, 0.0).via("identity")
def test_quat_to_euler_inverts_scipy_from_euler(roll, pitch, yaw):
    q = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_quat()
    for qq in (q, -q, 3.7 * q):  # same rotation: sign and scale of q do not matter
        e = quat_to_euler(qq[None])[0]
        assert ang_dist(e, [roll, pitch, yaw]).max() <= 1e-9
        # documented ranges: roll, yaw in [-pi, pi), pitch in [-pi/2, pi/2]
        assert -PI <= e[0] < PI and -PI <= e[2] < PI and abs(e[1]) <= PI / 2


@props(100)
@given(full_angle, safe_pitch, full_angle)
def test_euler_to_quat_is_rz_ry_rx(roll, pitch, yaw):
    q = euler_to_quat([[roll, pitch, yaw]])[0]
    assert q[3] >= 0.0 and abs(np.linalg.norm(q) - 1.0) <= 1e-12
    # body -> reference rotation R = Rz(yaw) Ry(pitch) Rx(roll), built by hand
    np.testing.assert_allclose(Rotation.from_quat(q).as_matrix(), rot_z(yaw) @ rot_y(pitch) @ rot_x(roll),
                               rtol=0, atol=1e-12)
    # and the same rotation as scipy's, up to the quaternion's sign
    ref = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_quat()
    assert min(np.abs(q - ref).max(), np.abs(q + ref).max()) <= 1e-12
    # round trip through the package's own pair
    assert ang_dist(quat_to_euler(q[None])[0], [roll, pitch, yaw]).max() <= 1e-9


def test_quat_to_euler_half_open_range_regression():
    """scipy returns +pi for a half turn about z or x; the package documents [-pi, pi)."""
    half_z, half_x = [0.0, 0.0, 1.0, 0.0], [1.0, 0.0, 0.0, 0.0]
    e = quat_to_euler([half_z, half_x])
    np.testing.assert_array_equal(e, [[0.0, 0.0, -PI], [-PI, 0.0, 0.0]])


# ======================================================================================
# 2. Angle wrapping
# ======================================================================================
finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
SEAM = [PI, -PI, 3 * PI, -3 * PI, float(np.nextafter(-PI, -4)), float(np.nextafter(PI, 4)),
        float(np.nextafter(PI, 0)), float(np.nextafter(-PI, 0)), 0.0, -0.0, 5e-324, TAU]


@props(100)
@given(finite)
@example(PI).via("exactly pi")
@example(-PI).via("exactly -pi")
@example(float(np.nextafter(-PI, -4))).via("just below -pi: rounds to +pi before the fix")
@example(float(np.nextafter(-3 * PI, -10))).via("just below -3 pi")
def test_wrap_range_and_reference(x):
    w = float(wrap(x))
    assert -PI <= w < PI
    # IEEE remainder is exact: wrap may only differ by the rounding of x + pi
    assert ang_dist(w, math.remainder(x, TAU)) <= 2 * ulp(abs(x) + PI)


@props(100)
@given(finite, st.integers(-1000, 1000))
def test_wrap_is_2pi_periodic(x, k):
    shifted = x + TAU * k
    tol = 2 * ulp(abs(x) + PI) + 2 * ulp(abs(shifted) + PI) + ulp(abs(shifted))
    assert ang_dist(wrap(shifted), wrap(x)) <= tol


@props(100)
@given(finite)
@example(PI)
@example(float(np.nextafter(PI, 0)))
def test_wrap_idempotent(x):
    w = wrap(x)
    ww = wrap(w)
    assert -PI <= ww < PI
    # (w + pi) - pi can round by one ulp of pi (and near the seam flip pi - ulp to -pi): the
    # same angle either way
    assert ang_dist(ww, w) <= 2 * ulp(PI)


def test_wrap_seam_values_regression():
    w = wrap(np.array(SEAM))
    assert ((w >= -PI) & (w < PI)).all(), w
    assert float(wrap(PI)) == -PI and float(wrap(-PI)) == -PI
    assert float(wrap(np.nextafter(-PI, -4))) == -PI  # was +pi before the fix
    assert isinstance(wrap(1.0), float)  # a numpy scalar for scalar input, as before


@props(100)
@given(st.lists(st.tuples(finite, finite), min_size=1, max_size=20))
@example([(PI, -PI), (-PI, PI), (0.0, PI), (PI, 0.0)])
def test_angle_diff_is_wrapped_difference(pairs):
    a, b = np.array(pairs).T
    d = angle_diff(a, b)
    np.testing.assert_array_equal(d, wrap(a - b))
    np.testing.assert_array_equal(angle_diff(a, b, wrapped=False), a - b)
    assert (np.abs(d) <= PI).all() and ((d >= -PI) & (d < PI)).all()
    # antisymmetric as an angle (at the seam -pi and -(-pi) = pi are the same angle)
    assert (ang_dist(angle_diff(b, a), -d) <= 4 * np.spacing(np.abs(a - b) + PI)).all()


# ======================================================================================
# 3. Windows and stitching
# ======================================================================================
trailing = st.sampled_from([(), (1,), (3,), (2, 2)])


@st.composite
def recording(draw: st.DrawFn) -> tuple[np.ndarray, int]:
    length = draw(st.integers(2, 40))
    n = length + draw(st.integers(0, 150))
    shape = (n, *draw(trailing))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    kind = draw(st.sampled_from(["int", "float64", "float32"]))
    if kind == "int":  # integer-valued floats: the overlap mean of equal values is exact
        x = rng.integers(-1000, 1000, size=shape).astype(float)
    else:
        x = rng.normal(0.0, 3.0, size=shape).astype(kind)
    return x, length


@props(80)
@given(recording())
def test_overlap_average_of_sliding_windows_is_identity(data):
    x, length = data
    n = len(x)
    win = sliding_windows(x, length)
    assert win.shape == (n - length + 1, length, *x.shape[1:])
    for j in {0, len(win) // 2, len(win) - 1}:  # window j is x[j:j+L]
        np.testing.assert_array_equal(win[j], x[j : j + length])
    out = stitch_overlap_average(win, n)
    assert out.shape == x.shape and out.dtype == np.result_type(x.dtype, np.float32)
    if x.dtype == np.float64 and np.array_equal(x, np.round(x)):
        np.testing.assert_array_equal(out, x)
    else:  # a mean of up to L equal values: a few ulps
        np.testing.assert_allclose(out, x, rtol=8 * np.finfo(x.dtype).eps, atol=0)
    np.testing.assert_array_equal(stitch_overlap_average(sliding_windows(x, length, copy=True), n), out)


@props(80)
@given(recording())
def test_tiles_cover_all_but_the_tail_and_leave_it_nan(data):
    x, length = data
    n = len(x)
    tiling = tile_windows(x, length)
    covered = n - n % length
    assert tiling.tail == n % length and tiling.n_covered == covered and tiling.n_total == n
    np.testing.assert_array_equal(tiling.starts, np.arange(n // length) * length)
    out = stitch_tiles(tiling.windows, n)
    assert out.shape == x.shape
    np.testing.assert_array_equal(out[:covered], x[:covered])
    assert np.isnan(out[covered:]).all()
    assert np.isfinite(out[:covered]).all()
    # the authors' loop range(0, N - L, L): one window fewer when the last one ends at N
    if n > length:
        authors = tile_windows(x, length, authors_range=True)
        assert len(authors.windows) == len(range(0, n - length, length))
        assert 1 <= authors.tail <= length
        np.testing.assert_array_equal(stitch_tiles(authors.windows, n)[: authors.n_covered],
                                      x[: authors.n_covered])


# ======================================================================================
# 4. The KF on exact, noise-free sensors follows a known trajectory
# ======================================================================================
FS = 100.0
DT = 1.0 / FS
N_KF = 300  # 3 s
INCLINATION = math.radians(60.0)
MAG_REF = 48.0 * np.array([math.cos(INCLINATION), 0.0, -math.sin(INCLINATION)])  # x north, z up [µT]


def sinusoids(c, a, f, p, t):
    """Angles, Euler rates and their derivatives of ``c + a sin(2 pi f t + p)`` per column."""
    w = 2.0 * np.pi * np.asarray(f)
    arg = np.outer(t, w) + p
    return c + a * np.sin(arg), a * w * np.cos(arg), -a * w * w * np.sin(arg)


def body_rates(e, de):
    """Body angular rate (p, q, r) from intrinsic ZYX Euler angles and their rates (closed form)."""
    phi, th = e[:, 0], e[:, 1]
    return np.column_stack([de[:, 0] - de[:, 2] * np.sin(th),
                            de[:, 1] * np.cos(phi) + de[:, 2] * np.cos(th) * np.sin(phi),
                            -de[:, 1] * np.sin(phi) + de[:, 2] * np.cos(th) * np.cos(phi)])


def euler_rates_ref(w, phi, th):
    """Inverse kinematics, written out here (the KF's input at the given roll/pitch)."""
    p, q, r = w.T
    s = np.sin(phi) * q + np.cos(phi) * r
    return np.column_stack([p + np.tan(th) * s, np.cos(phi) * q - np.sin(phi) * r, s / np.cos(th)])


def heading_ref(m, phi, th):
    """Heading of the body field de-rotated by roll then pitch (scipy), for a field with no y part."""
    h = Rotation.from_euler("YX", np.column_stack([th, phi])).apply(m)
    return np.arctan2(-h[:, 1], h[:, 0])


def error_gains(k, n):
    """For one (angle, bias) block with gains ``k[t] = (k_angle, k_bias)``: the largest l1 norm,
    over t, of the impulse responses from a prediction disturbance and from a measurement
    error to the angle error.

    Error recursion (e = true - estimated angle, b = estimated bias, true bias 0; d = what the
    prediction misses, m = measurement - truth)::

        e' = e + dt b + d;   e <- (1 - k0) e' - k0 m;   b <- b + k1 (e' + m)
    """
    sd = np.zeros((2, n))
    sm = np.zeros((2, n))
    gd = gm = 0.0
    for t in range(n):
        k0, k1 = k[min(t, len(k) - 1)]
        a = np.array([[1.0 - k0, (1.0 - k0) * DT], [k1, 1.0 + k1 * DT]])
        sd[:, :t] = a @ sd[:, :t]
        sm[:, :t] = a @ sm[:, :t]
        sd[:, t] = (1.0 - k0, k1)
        sm[:, t] = (-k0, k1)
        gd = max(gd, float(np.abs(sd[0, : t + 1]).sum()))
        gm = max(gm, float(np.abs(sm[0, : t + 1]).sum()))
    return gd, gm


@st.composite
def trajectory(draw: st.DrawFn):
    """A smooth attitude with either pitch = 0 or roll = 0 (then the accelerometer's roll/pitch
    formulas are exact), yaw kept inside (-pi, pi) (no heading wrap), and a KF setting."""
    level = draw(st.sampled_from(["pitch", "roll"]))  # the angle held at zero
    u = st.floats(0.0, 1.0)
    c = np.array([draw(st.floats(-0.3, 0.3)), draw(st.floats(-0.3, 0.3)), draw(st.floats(-2.0, 2.0))])
    a = np.array([draw(u) * 0.6, draw(u) * 0.6, draw(u) * 0.8])
    f = np.array([draw(st.floats(0.05, 1.0)) for _ in range(3)])
    p = np.array([draw(st.floats(-PI, PI)) for _ in range(3)])
    j = 1 if level == "pitch" else 0
    c[j] = a[j] = 0.0
    q, r = draw(st.sampled_from([(1.0, 1.0), (1e-2, 1e-1), (1e-4, 1e-2)]))  # paper's identities ... gyro-heavy
    return c, a, f, p, q, r


@props(30)
@given(trajectory())
def test_kf_follows_exact_trajectory_within_integration_error(params):
    """Noise-free gyro, accelerometer (tilt convention) and magnetometer of a known smooth
    attitude. Both sources are exact, so what remains is (i) the one-step integration error of
    the prediction, ``d_t = x_t - x_{t-1} - dt * u_t`` (rate taken at sample t, kinematics at
    the previous angles), and (ii) for yaw the heading measured with the *previous* roll/pitch,
    ``m_t``. The filter's error is a linear response to them; its l1 gain over the filter's
    own gain sequence times ``max |d|`` (and ``max |m|``) bounds the error to first order. The
    factor 1.5 covers the neglected second-order terms (rates and heading evaluated at the
    estimate rather than the truth, which differ by the filter's own small error); the
    observed error stays below 1.0 x the first-order bound on 200 random trajectories.
    """
    c, a, f, p, q, r = params
    t = np.arange(-1, N_KF) * DT  # the filter's x0 is the state one step before sample 0
    e, de, _ = sinusoids(c, a, f, p, t)
    gyro = body_rates(e, de)
    rot = Rotation.from_euler("ZYX", e[:, ::-1])
    acc = rot.inv().apply([0.0, 0.0, 1.0])  # tilt convention: R.T @ up
    mag = rot.inv().apply(MAG_REF)

    # the closed-form body rate is the rotation's derivative (central difference, scipy)
    h = 1e-6
    for i in (1, N_KF // 2, N_KF):
        ee, _, _ = sinusoids(c, a, f, p, np.array([t[i] - h, t[i] + h]))
        pair = Rotation.from_euler("ZYX", ee[:, ::-1])
        np.testing.assert_allclose((pair[0].inv() * pair[1]).as_rotvec() / (2 * h), gyro[i], atol=1e-6)

    cfg = KFConfig(Q=q * np.eye(6), R=r * np.eye(3), x0=[e[0, 0], 0.0, e[0, 1], 0.0, e[0, 2], 0.0])
    res = kalman_filter(gyro[1:], acc[1:], mag[1:], DT, cfg, init_euler=e[0])
    truth = e[1:]
    # the roll/pitch measurements are exact for these attitudes
    np.testing.assert_allclose(res.measurements[:, :2], truth[:, :2], rtol=0, atol=1e-12)

    d = truth - e[:-1] - DT * euler_rates_ref(gyro[1:], e[:-1, 0], e[:-1, 1])
    m = ang_dist(heading_ref(mag[1:], e[:-1, 0], e[:-1, 1]), truth[:, 2])
    seq = gain_sequence(DT, cfg, n_max=N_KF)
    bound = np.empty(3)
    for j in range(3):
        gd, gm = error_gains(seq.K[:, [2 * j, 2 * j + 1], j], N_KF)
        bound[j] = gd * np.abs(d[:, j]).max() + (gm * m.max() if j == 2 else 0.0)
    tol = 1.5 * bound + 1e-12
    err = ang_dist(res.euler, truth).max(axis=0)
    assert (err <= tol).all(), f"error {err} > tolerance {tol}"
    assert tol[:2].max() < 5e-2 and tol[2] < 0.2  # the bound is tight enough to mean something (amplitudes reach 0.6 rad)


# ======================================================================================
# 5. Loaders: random corruptions give DataError naming the file (and line), never a crash
#    and never a silent result
# ======================================================================================
BAD_CELLS = ["", " ", "abc", "nan", "NaN", "-nan", "inf", "-inf", "Infinity", "1e999", "1.5e", "--1", "0x10",
             "1.0.0", "null", "N/A", "#", '"', "'", "1_0", "١٢", "１２", "\x00", "\\", "1 2", "+", "."]
"""Cell texts that are not finite numbers (underscores and non-ASCII digits included:
Python's float() reads them, a CSV number never has them)."""
NON_UTF8 = [b"\xff", b"\xfe", b"\xc3", b"\x80", b"\xed\xa0\x80", b"\xf8\x88\x80\x80\x80"]
KINDS = ["cell_text", "cell_number", "cell_python_number", "truncate_row", "extend_row", "delete_row", "append_bytes",
         "non_utf8", "truncate_file", "empty"]
_DECIMAL_REF = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")
cell_text = st.one_of(
    st.sampled_from(BAD_CELLS),
    st.text(st.characters(blacklist_characters=',\n"', blacklist_categories=("Cs",)), max_size=6),
)
number_text = st.floats(-1e6, 1e6, allow_nan=False).map(repr) | st.integers(-10**6, 10**6).map(str)


@st.composite
def python_only_number(draw: st.DrawFn) -> str:
    """A number spelled so that Python's float() reads it but no CSV reader does: an
    underscore between digits, or the digits in another script (full-width, Arabic-Indic)."""
    text = str(draw(st.integers(10, 10**6))) + draw(st.sampled_from(["", ".5", "e-3"]))
    how = draw(st.sampled_from(["underscore", "fullwidth", "arabic"]))
    if how == "underscore":
        i = draw(st.integers(1, len(str(text).split(".")[0].split("e")[0]) - 1))
        return text[:i] + "_" + text[i:]
    zero = {"fullwidth": 0xFF10, "arabic": 0x0660}[how]
    return "".join(chr(zero + int(ch)) if ch.isdigit() else ch for ch in text)


def lines_of(raw: bytes) -> list[bytes]:
    """Lines as the documented format counts them: split at \\n, a final \\n ends the last line."""
    parts = raw.split(b"\n")
    return parts[:-1] if parts[-1] == b"" else parts


def ref_parse(lines: list[bytes], ncols: int, used: list[int], first_line: int):
    """Reference CSV reading: (1-based line of the first error, None) or (None, values).

    All lines are checked for the field count before any value (as documented); then cells of
    the used columns, row by row, must be plain decimal numbers and finite.
    """
    rows = [ln.decode("utf-8", errors="replace").split(",") for ln in lines]
    for i, fields in enumerate(rows):
        if len(fields) != ncols:
            return first_line + i, None
    out = np.empty((len(rows), len(used)))
    for i, fields in enumerate(rows):
        for j, col in enumerate(used):
            cell = fields[col].strip()
            value = float(cell) if _DECIMAL_REF.fullmatch(cell) else math.nan
            if not math.isfinite(value):
                return first_line + i, None
            out[i, j] = value
    return None, out


@st.composite
def corruption(draw: st.DrawFn, kind: str, n_lines: int, ncols: int, first: int = 0):
    """One random damage of ``kind`` to a file of ``n_lines`` data lines (after ``first`` header lines)."""
    line = draw(st.integers(first, first + n_lines - 1))
    col = draw(st.integers(0, ncols - 1))
    arg: object = None
    if kind == "cell_text":
        arg = draw(cell_text)
    elif kind == "cell_number":
        arg = draw(number_text)
    elif kind == "cell_python_number":
        arg = draw(python_only_number())
    elif kind == "truncate_row":
        arg = draw(st.integers(1, ncols))  # fields dropped (ncols: the line keeps an empty tail)
    elif kind == "extend_row":
        arg = draw(st.sampled_from(["", "1.0", "abc", "1.0,2.0"]))
    elif kind == "append_bytes":
        arg = draw(st.binary(min_size=1, max_size=24))
    elif kind == "non_utf8":
        arg = (draw(st.sampled_from(NON_UTF8)), draw(st.floats(0.0, 1.0)))
    elif kind == "truncate_file":
        arg = draw(st.floats(0.0, 1.0))
    return kind, line, col, arg


def corrupt(raw: bytes, damage, header_bytes: int = 0) -> bytes:
    """Apply one damage; byte positions are drawn after the first ``header_bytes`` bytes."""
    kind, line, col, arg = damage
    lines = lines_of(raw)
    body = len(raw) - header_bytes
    if kind.startswith("cell_"):
        fields = lines[line].split(b",")
        fields[col] = arg.encode("utf-8")
        lines[line] = b",".join(fields)
    elif kind == "truncate_row":
        lines[line] = b",".join(lines[line].split(b",")[:-arg])
    elif kind == "extend_row":
        lines[line] += b"," + arg.encode()
    elif kind == "delete_row":
        del lines[line]
    elif kind == "append_bytes":
        return raw + arg
    elif kind == "non_utf8":
        at = header_bytes + int(arg[1] * body)
        return raw[:at] + arg[0] + raw[at:]
    elif kind == "truncate_file":
        return raw[: header_bytes + int(arg * body)]
    elif kind == "empty":
        return b""
    return b"\n".join(lines) + b"\n"


def assert_names(err: DataError, path: Path, line: int | None = None) -> None:
    msg = str(err)
    assert str(path) in msg, msg
    if line is not None:
        assert re.search(rf"\bline {line}\b", msg), f"expected line {line}: {msg}"


OX_ROWS = 40
OX_IMU, OX_VI, _ = synthetic_oxiod(n=OX_ROWS, seed=3)


@pytest.mark.parametrize("kind", KINDS)
@props(16)
@given(which=st.sampled_from(["imu", "vi"]), data=st.data())
def test_oxiod_corruptions_raise_data_error_or_load_exactly(kind, which, data):
    ncols = 16 if which == "imu" else 9
    damage = data.draw(corruption(kind, OX_ROWS, ncols), label="damage")
    with tempfile.TemporaryDirectory() as tmp:
        imu_p, vi_p = Path(tmp) / "imu1.csv", Path(tmp) / "vi1.csv"
        write_rows(imu_p, OX_IMU)
        write_rows(vi_p, OX_VI)
        target = imu_p if which == "imu" else vi_p
        target.write_bytes(corrupt(target.read_bytes(), damage))
        imu_lines, vi_lines = lines_of(imu_p.read_bytes()), lines_of(vi_p.read_bytes())

        # what the documented checks expect, in their documented order
        expected: tuple[list[Path], int | None] | None = None
        if len(imu_lines) != len(vi_lines):
            expected = [imu_p, vi_p], None  # row counts must match: both files named
        elif len(imu_lines) < oxiod.MIN_SAMPLES:
            expected = [imu_p], None
        else:
            bad_imu, imu_vals = ref_parse(imu_lines, 16, list(range(1, 16)), 1)  # time column unused
            bad_vi, vi_vals = ref_parse(vi_lines, 9, list(range(1, 9)), 1)
            if bad_imu is not None:
                expected = [imu_p], bad_imu
            elif bad_vi is not None:
                expected = [vi_p], bad_vi

        event("DataError" if expected else "loads")
        if expected is not None:
            with pytest.raises(DataError) as info:
                oxiod.load_recording(imu_p)
            paths, line = expected
            for path in paths:
                assert_names(info.value, path, line)
        else:  # a legitimate file (e.g. a number replaced by a number): loads, values intact
            rec = oxiod.load_recording(imu_p)
            assert len(rec) == len(imu_lines)
            close = dict(rtol=1e-15, atol=0)
            np.testing.assert_allclose(rec.meta["phone_euler"], imu_vals[:, 0:3], **close)
            np.testing.assert_allclose(rec.gyro, imu_vals[:, 3:6], **close)
            np.testing.assert_allclose(rec.acc, imu_vals[:, 6:9] - imu_vals[:, 9:12], **close)
            np.testing.assert_allclose(rec.mag, imu_vals[:, 12:15], **close)
            np.testing.assert_allclose(rec.meta["vicon_frame"], vi_vals[:, 0], **close)
            np.testing.assert_allclose(rec.meta["vicon_position"], vi_vals[:, 1:4], **close)
            np.testing.assert_allclose(rec.quat, vi_vals[:, 4:8], **close)


UCS_ROWS = 40
UCS_NCOLS = 23
UCS_UNUSED = {1}  # field.header.seq
UCS_USED = [c for c in range(UCS_NCOLS) if c not in UCS_UNUSED]
UCS_GYRO = [17, 18, 19]
UCS_QUAT = [6, 7, 8, 9]


@pytest.mark.parametrize("kind", KINDS)
@props(16)
@given(data=st.data())
def test_ucs_corruptions_raise_data_error_or_load_exactly(kind, data):
    damage = data.draw(corruption(kind, UCS_ROWS, UCS_NCOLS, first=1), label="damage")
    with tempfile.TemporaryDirectory() as tmp:
        path = write_ucs(Path(tmp) / "imu_adis.txt", ucs_signals(n=UCS_ROWS))
        raw = path.read_bytes()
        header_bytes = raw.index(b"\n") + 1  # byte-level damage goes after the header row
        path.write_bytes(corrupt(raw, damage, header_bytes))
        lines = lines_of(path.read_bytes())

        expected: int | None | str = None
        if not lines or len(lines) - 1 < ucs.MIN_SAMPLES:
            expected = "file"
        else:
            bad, vals = ref_parse(lines[1:], UCS_NCOLS, UCS_USED, 2)
            if bad is not None:
                expected = bad
            else:  # %time must increase (compared exactly: int or float as written)
                cells = [ln.decode("utf-8", errors="replace").split(",")[0].strip() for ln in lines[1:]]
                stamps = [int(s) if re.fullmatch(r"[+-]?[0-9]+", s) else float(s) for s in cells]
                drop = [i for i in range(1, len(stamps)) if stamps[i] <= stamps[i - 1]]
                if drop:
                    expected = drop[0] + 2  # 1-based line of the sample that does not increase

        event("loads" if expected is None else "DataError")
        if expected is not None:
            with pytest.raises(DataError) as info:
                ucs.load_recording(path)
            assert_names(info.value, path, None if expected == "file" else expected)
        else:
            rec = ucs.load_recording(path)
            assert len(rec) == len(lines) - 1
            used = {c: j for j, c in enumerate(UCS_USED)}
            np.testing.assert_allclose(rec.gyro, vals[:, [used[c] for c in UCS_GYRO]], rtol=1e-15, atol=0)
            np.testing.assert_allclose(rec.quat, vals[:, [used[c] for c in UCS_QUAT]], rtol=1e-15, atol=0)


# ---------------------------------------------------------------- regressions found above
@pytest.mark.parametrize("cell", ["-40.1_2", "١٢", "１２"])
def test_cell_python_float_accepts_but_csv_does_not_is_rejected(cell, tmp_path):
    """Python's float() reads '-40.1_2' as -40.12 and Arabic-Indic / full-width digits as 12;
    the fallback parser used them when pandas refused the cell, so the load succeeded silently."""
    imu_p, vi_p = tmp_path / "imu1.csv", tmp_path / "vi1.csv"
    write_rows(imu_p, OX_IMU)
    write_rows(vi_p, OX_VI)
    lines = imu_p.read_text().splitlines()
    fields = lines[4].split(",")
    fields[13] = cell  # magnetic field x, a used column
    lines[4] = ",".join(fields)
    imu_p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(DataError) as info:
        oxiod.load_recording(imu_p)
    assert_names(info.value, imu_p, 5)
    assert "column 14 (magnetic field x)" in str(info.value) and repr(cell) in str(info.value)


def test_ucs_file_with_utf8_bom_loads(tmp_path):
    """A UTF-8 byte-order mark before '%time' (a file re-saved by a Windows editor) used to hide
    the time column: 'header row lacks column(s) %time'."""
    path = write_ucs(tmp_path / "imu_adis.txt", ucs_signals(n=UCS_ROWS))
    plain = ucs.load_recording(path)
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    rec = ucs.load_recording(path)
    assert len(rec) == len(plain) and rec.fs == plain.fs
    np.testing.assert_array_equal(rec.gyro, plain.gyro)
    np.testing.assert_array_equal(rec.meta["timestamps_raw"], plain.meta["timestamps_raw"])
