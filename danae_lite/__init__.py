"""danae_lite: the small library under the DANAE book.

Modules, each with one job:

* :mod:`~danae_lite.angles`     Euler/quaternion conventions and angle wrapping
* :mod:`~danae_lite.config`     fast mode, data directory, seeds, device
* :mod:`~danae_lite.recording`  the one :class:`Recording` type and :class:`DataError`
* :mod:`~danae_lite.oxiod`, :mod:`~danae_lite.ucs`  loaders for the real datasets
* :mod:`~danae_lite.broad`      the BROAD benchmark: loader, its error metric, its reference filters
* :mod:`~danae_lite.simulate`   a deterministic IMU/AHRS simulator with exact ground truth
* :mod:`~danae_lite.datasets`   data-directory lookup with the simulator as fallback
* :mod:`~danae_lite.groundtruth`  glitches of the optical ground truth
* :mod:`~danae_lite.alignment`  sensor-to-body rotation and magnetic north from training data
* :mod:`~danae_lite.kalman`     the paper's linear attitude Kalman filter
* :mod:`~danae_lite.filters`    established attitude filters (Fusion, VQF, Madgwick, Mahony, RIANN)
* :mod:`~danae_lite.metrics`    the paper's error metrics and reported numbers
* :mod:`~danae_lite.windows`    windows and stitching
* :mod:`~danae_lite.model`, :mod:`~danae_lite.train`  the DANAE networks, training, inference
* :mod:`~danae_lite.gemm_conv`  their convolutions as matrix products (channels-last)
* :mod:`~danae_lite.streaming`  the causal network one sample at a time
* :mod:`~danae_lite.pipeline`   KF -> one DANAE per angle and seed -> metric tables
* :mod:`~danae_lite.baselines`, :mod:`~danae_lite.variants`  methods of the leaderboard
* :mod:`~danae_lite.leaderboard`  every method on the same recordings and metrics
* :mod:`~danae_lite.plots`      one plotting style shared by every chapter
* :mod:`~danae_lite.figures`    the paper's figures recreated (KF above, DANAE below)
* :mod:`~danae_lite.cli`        ``python -m danae_lite reproduce|leaderboard``
* :mod:`~danae_lite.book`       the common first cell of every chapter and ``make execute``
"""
from .angles import ANGLES, angle_diff, euler_to_quat, quat_to_euler, wrap
from .config import data_dir, default_device, fast_mode, seed_everything
from .recording import DataError, Recording

__all__ = [
    "ANGLES",
    "DataError",
    "Recording",
    "angle_diff",
    "data_dir",
    "default_device",
    "euler_to_quat",
    "fast_mode",
    "quat_to_euler",
    "seed_everything",
    "wrap",
]
__version__ = "0.1.0"
