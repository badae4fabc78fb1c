"""danae_lite: the small library under the DANAE book.

Three layers, one folder each; imports run one way only, entry points -> research engine -> core
(``tests/test_architecture.py`` reads each module's layer from its folder and keeps it so). A new
module goes into ``core/`` if chapters 1-4 need it, else into ``research/``; only settings,
chapter setup and the command line sit at the top (book maintenance, re-execution and the
pages' generated blocks, is not part of the package: ``tools/``).

**Core** (``danae_lite/core/``) -- what chapters 1-4 need:

* :mod:`~danae_lite.core.angles`       Euler/quaternion conventions, frames (ENU/NWU), gravity, angle wrapping
* :mod:`~danae_lite.core.recording`    the one :class:`Recording` type and :class:`DataError`
* :mod:`~danae_lite.core.oxiod`, :mod:`~danae_lite.core.ucs`  loaders of the paper's two datasets
* :mod:`~danae_lite.core.groundtruth`  glitches of the optical ground truth
* :mod:`~danae_lite.core.simulate`     a deterministic IMU/AHRS simulator with exact ground truth
* :mod:`~danae_lite.core.datasets`     the paper's experiments from a data directory, or the simulator
* :mod:`~danae_lite.core.alignment`    sensor-to-body rotation and magnetic north from training data
* :mod:`~danae_lite.core.kf_model`     the paper's attitude model: state, measurements, settings (:class:`KFConfig`)
* :mod:`~danae_lite.core.kf_gains`     its gain and covariance sequence, and the steady state (DARE)
* :mod:`~danae_lite.core.kalman`       the paper's linear attitude Kalman filter (one step by the book; the fast loop)
* :mod:`~danae_lite.core.metrics`      the paper's error metrics and reported numbers
* :mod:`~danae_lite.core.windows`      windows and stitching
* :mod:`~danae_lite.core.model`        the DANAE networks; :mod:`~danae_lite.core.gemm_conv` their convolutions as matrix products
* :mod:`~danae_lite.core.seeding`      seeds and device; :mod:`~danae_lite.core.train_types` the training settings and result
* :mod:`~danae_lite.core.train`        the one training loop; :mod:`~danae_lite.core.inference` the one batch predict path
* :mod:`~danae_lite.core.checkpoints`  one file per trained network
* :mod:`~danae_lite.core.networks`     many trainings at once: worker processes and the network cache
* :mod:`~danae_lite.core.paper_danae`  the paper's DANAE as one estimator (a network per angle and seed)
* :mod:`~danae_lite.core.scoring`      predictions -> metric rows, one rule for every table
* :mod:`~danae_lite.core.pipeline`     the paper's run: KF -> DANAE -> Tables 1-2 and Figures 1-2
* :mod:`~danae_lite.core.plots`        one plotting style; :mod:`~danae_lite.core.figures` the paper's figures recreated

**Research engine** (``danae_lite/research/``) -- chapters 5 onward:

* :mod:`~danae_lite.research.broad`          the BROAD benchmark's trials and its train/test split
* :mod:`~danae_lite.research.oxiod_motions`  the OxIOD recordings grouped by motion, for cross-validation
* :mod:`~danae_lite.research.methods`      the method protocol (:class:`~danae_lite.research.methods.Method`) and its objectives
* :mod:`~danae_lite.research.memo`         each distinct filter run and network output computed once per process
* :mod:`~danae_lite.research.filters`      established attitude filters (Fusion, VQF, Madgwick, Mahony, RIANN)
* :mod:`~danae_lite.research.ahrs_grid`    Madgwick's and Mahony's filters for a whole grid of gains in one pass
* :mod:`~danae_lite.research.kf_offline`   the KF after the fact: innovations and their NIS, the RTS smoother
* :mod:`~danae_lite.research.kf_grid`      the paper's KF for a whole grid of settings in one pass (tuning)
* :mod:`~danae_lite.research.baselines`    classical methods of the leaderboard (tuned KF, low-pass, linear map, ...)
* :mod:`~danae_lite.research.features`     input channels and causal network shared by the learned methods
* :mod:`~danae_lite.research.variants`     DANAE behind any filter, multi-input, causal, ablations
* :mod:`~danae_lite.research.denoiser`     the recommended learned denoiser (DANAE-res)
* :mod:`~danae_lite.research.fallback`     DANAE-res with a per-sample fallback and a calibrated error bar
* :mod:`~danae_lite.research.streaming`    causal networks one sample at a time
* :mod:`~danae_lite.research.registry`     leaderboard names -> methods
* :mod:`~danae_lite.research.broad_benchmark`  the BROAD metric, its reference filters, the published figures
* :mod:`~danae_lite.research.leaderboard`  every method on the same recordings and metrics
* :mod:`~danae_lite.research.crossval`     folds: leave one recording out, transfer between motions, BROAD
* :mod:`~danae_lite.research.verdicts`     the wording of a verdict drawn from a difference over seeds or recordings

**Entry points** (``danae_lite/``):

* :mod:`~danae_lite.config`       the run settings, read from flags and ``DANAE_*`` variables (only here)
* :mod:`~danae_lite.book`         the common first cell of every chapter (``setup``); ``glue``/``prose``: results in the prose
* :mod:`~danae_lite.cli`          ``python -m danae_lite reproduce|leaderboard``; :mod:`~danae_lite.cli_data` its data flags -> recordings
"""
from .core._version import __version__
from .core.angles import ANGLES, angle_diff, euler_to_quat, quat_to_euler, wrap
from .core.recording import DataError, Recording
from .core.seeding import default_device, seed_everything

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
