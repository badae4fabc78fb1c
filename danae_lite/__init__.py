"""danae_lite: the small library under the DANAE book.

Three layers; imports run one way only, entry points -> research engine -> core
(``tests/test_architecture.py`` keeps it so).

**Core** -- what chapters 1-4 need:

* :mod:`~danae_lite.angles`       Euler/quaternion conventions, frames (ENU/NWU), gravity, angle wrapping
* :mod:`~danae_lite.recording`    the one :class:`Recording` type and :class:`DataError`
* :mod:`~danae_lite.oxiod`, :mod:`~danae_lite.ucs`, :mod:`~danae_lite.broad`  loaders of the real datasets
* :mod:`~danae_lite.groundtruth`  glitches of the optical ground truth
* :mod:`~danae_lite.simulate`     a deterministic IMU/AHRS simulator with exact ground truth
* :mod:`~danae_lite.datasets`     the experiments' recordings from a data directory, or the simulator
* :mod:`~danae_lite.alignment`    sensor-to-body rotation and magnetic north from training data
* :mod:`~danae_lite.kf_model`     the paper's attitude model: state, measurements, settings (:class:`KFConfig`)
* :mod:`~danae_lite.kf_gains`     its gain and covariance sequence, and the steady state (DARE)
* :mod:`~danae_lite.kalman`       the paper's linear attitude Kalman filter (one step by the book; the fast loop)
* :mod:`~danae_lite.metrics`      the paper's error metrics and reported numbers
* :mod:`~danae_lite.windows`      windows and stitching
* :mod:`~danae_lite.model`        the DANAE networks; :mod:`~danae_lite.gemm_conv` their convolutions as matrix products
* :mod:`~danae_lite.seeding`      seeds and device; :mod:`~danae_lite.train_types` the training settings and result
* :mod:`~danae_lite.train`        the one training loop and the one batch predict path
* :mod:`~danae_lite.checkpoints`  one file per trained network
* :mod:`~danae_lite.networks`     many trainings at once: worker processes and the network cache
* :mod:`~danae_lite.paper_danae`  the paper's DANAE as one estimator (a network per angle and seed)
* :mod:`~danae_lite.scoring`      predictions -> metric rows, one rule for every table
* :mod:`~danae_lite.pipeline`     the paper's run: KF -> DANAE -> Tables 1-2 and Figures 1-2
* :mod:`~danae_lite.plots`        one plotting style; :mod:`~danae_lite.figures` the paper's figures recreated

**Research engine** -- chapters 5 onward:

* :mod:`~danae_lite.methods`      the method protocol (:class:`~danae_lite.methods.Method`) and its objectives
* :mod:`~danae_lite.filters`      established attitude filters (Fusion, VQF, Madgwick, Mahony, RIANN)
* :mod:`~danae_lite.kf_offline`   the KF after the fact: innovations and their NIS, the RTS smoother
* :mod:`~danae_lite.kf_grid`      the paper's KF for a whole grid of settings in one pass (tuning)
* :mod:`~danae_lite.baselines`    classical methods of the leaderboard (tuned KF, low-pass, linear map, ...)
* :mod:`~danae_lite.features`     input channels and causal network shared by the learned methods
* :mod:`~danae_lite.variants`     DANAE behind any filter, multi-input, causal, ablations
* :mod:`~danae_lite.denoiser`     the recommended learned denoiser (DANAE-res)
* :mod:`~danae_lite.streaming`    causal networks one sample at a time
* :mod:`~danae_lite.registry`     leaderboard names -> methods
* :mod:`~danae_lite.broad_benchmark`  the BROAD metric, its reference filters, the published figures
* :mod:`~danae_lite.leaderboard`  every method on the same recordings and metrics
* :mod:`~danae_lite.crossval`     folds: leave one recording out, transfer between motions, BROAD

**Entry points**:

* :mod:`~danae_lite.config`       the run settings, read from flags and ``DANAE_*`` variables (only here)
* :mod:`~danae_lite.book`         the common first cell of every chapter (``setup``)
* :mod:`~danae_lite.execute`      ``make execute``: re-executes the stale chapters and records each run
* :mod:`~danae_lite.cli`          ``python -m danae_lite reproduce|leaderboard``; :mod:`~danae_lite.cli_data` its data flags -> recordings
"""
from ._version import __version__
from .angles import ANGLES, angle_diff, euler_to_quat, quat_to_euler, wrap
from .recording import DataError, Recording
from .seeding import default_device, seed_everything

__all__ = [
    "ANGLES",
    "DataError",
    "Recording",
    "__version__",
    "angle_diff",
    "default_device",
    "euler_to_quat",
    "quat_to_euler",
    "seed_everything",
    "wrap",
]
