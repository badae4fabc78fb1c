"""danae_lite: the small library under the DANAE book, one room per concept.

Data flows one way, recording -> attitude filter -> windows -> DANAE -> stitched angles ->
metrics and figures, and imports point the same way: a room imports only rooms above it in
this map (``tests/test_architecture.py`` keeps it so, with no import circles and every module
listed here). Book maintenance (re-executing the chapters, the pages' generated blocks) is not
part of the package: ``tools/``.

* :mod:`~danae_lite.angles`  Euler/quaternion conventions, gravity, angle wrapping

**Recordings** (``data/``)

* :mod:`~danae_lite.data.frames`  the quaternion product; body -> ENU and body -> NWU quaternions
* :mod:`~danae_lite.data.recording`  the one :class:`~danae_lite.data.recording.Recording` type and :class:`~danae_lite.data.recording.DataError`
* :mod:`~danae_lite.data.parsing`  strict numeric parsing shared by the loaders
* :mod:`~danae_lite.data.oxiod`, :mod:`~danae_lite.data.ucs`  loaders of the paper's two datasets
* :mod:`~danae_lite.data.groundtruth`  glitches of the optical ground truth
* :mod:`~danae_lite.data.simulate`  a deterministic IMU/AHRS simulator with exact ground truth
* :mod:`~danae_lite.data.experiments`  the paper's experiments from a data directory, or the simulator
* :mod:`~danae_lite.data.alignment`  sensor-to-body rotation and magnetic north from training data
* :mod:`~danae_lite.data.broad`  the BROAD benchmark's trials and its train/test split
* :mod:`~danae_lite.data.oxiod_motions`  the OxIOD recordings grouped by motion, for cross-validation
* :mod:`~danae_lite.data.inventory`  a data folder file by file against the book's reference copies (SHA-256, rows, columns)
* :mod:`~danae_lite.data.fetch`  the public BROAD trials downloaded with pooch, checksums verified

**The Kalman filter** (``kalman/``)

* :mod:`~danae_lite.kalman.model`  the paper's attitude model: state, measurements, settings (:class:`~danae_lite.kalman.model.KFConfig`)
* :mod:`~danae_lite.kalman.gains`  its gain and covariance sequence, and the steady state (DARE)
* :mod:`~danae_lite.kalman.filter`  the filter: one step by the book, the fast loop
* :mod:`~danae_lite.kalman.grid`  the filter for a whole grid of settings in one pass (tuning)
* :mod:`~danae_lite.kalman.offline`  the filter after the fact: innovations and their NIS, the RTS smoother

**DANAE** (``danae/``)

* :mod:`~danae_lite.danae.windows`  windows and stitching
* :mod:`~danae_lite.danae.base`  what every DANAE network shares; :mod:`~danae_lite.danae.model` the authors' two
* :mod:`~danae_lite.danae.causal`  the causal network, for on-line use
* :mod:`~danae_lite.danae.seeding`  seeds and device; :mod:`~danae_lite.danae.train_types` the training settings and result
* :mod:`~danae_lite.danae.train`  the one training loop; :mod:`~danae_lite.danae.checkpoints` one file per trained network
* :mod:`~danae_lite.danae.networks`  many trainings at once: worker processes and the network cache
* :mod:`~danae_lite.danae.predict`  the one batch predict path

**Evaluation, figures, the paper**

* :mod:`~danae_lite.evaluate.metrics`  the paper's error metrics and reported numbers
* :mod:`~danae_lite.evaluate.scoring`  predictions -> metric rows, one rule for every table
* :mod:`~danae_lite.evaluate.comparison`  the paired comparison: two methods' errors unit by unit, a verdict table per question
* :mod:`~danae_lite.plots`  one plotting style for angles and methods
* :mod:`~danae_lite.paper.danae`  the paper's DANAE as one estimator (a network per angle and seed)
* :mod:`~danae_lite.paper.pipeline`  the paper's run: KF -> DANAE -> Tables 1-2 and Figures 1-2
* :mod:`~danae_lite.paper.reproduction`  its results: the per-seed study, the scores, the tables and files
* :mod:`~danae_lite.paper.figures`  the paper's figures recreated

**Research: past the paper** (``research/``)

* :mod:`~danae_lite.research.methods`  the method protocol (:class:`~danae_lite.research.methods.Method`) and its objectives
* :mod:`~danae_lite.research.memo`  each distinct filter run and network output computed once per process
* :mod:`~danae_lite.research.ahrs.filters`  established attitude filters (Fusion, VQF, Madgwick, Mahony, RIANN)
* :mod:`~danae_lite.research.ahrs.grid`  Madgwick's and Mahony's filters for a whole grid of gains in one pass
* :mod:`~danae_lite.research.ahrs.broad_reference`  Madgwick's and Mahony's filters as the BROAD benchmark ran them
* :mod:`~danae_lite.research.baselines`  classical methods of the leaderboard (constant, paper and tuned KF, library filters, ...)
* :mod:`~danae_lite.research.post_processing`  the leaderboard's post-processing of the KF output: low-pass filters, linear window map
* :mod:`~danae_lite.research.features`  input channels and causal network shared by the learned methods
* :mod:`~danae_lite.research.variants`  DANAE behind any filter, multi-input, causal, ablations
* :mod:`~danae_lite.research.danae_res`  the recommended learned denoiser (DANAE-res)
* :mod:`~danae_lite.research.danae_safe`  DANAE-res with a per-sample fallback and a calibrated error bar
* :mod:`~danae_lite.research.streaming`  causal networks one sample at a time
* :mod:`~danae_lite.research.registry`  leaderboard names -> methods
* :mod:`~danae_lite.research.broad_benchmark`  the BROAD metric and the published figures
* :mod:`~danae_lite.research.leaderboard`  every method on the same recordings and metrics
* :mod:`~danae_lite.research.crossval`  folds: leave one recording out, transfer between motions, BROAD

**Entry points**

* :mod:`~danae_lite.runtime`  the run settings, read from flags and ``DANAE_*`` variables (only here)
* :mod:`~danae_lite.book`  the common first cell of every chapter (``setup``); ``glue``/``prose``: results in the prose
* :mod:`~danae_lite.commands.data_flags`  the command line's data flags -> recordings; :mod:`~danae_lite.commands.prepare` what the commands share
* :mod:`~danae_lite.commands.method_names`  the leaderboard's method names as a static table (a fast ``--help``)
* :mod:`~danae_lite.commands.data`, :mod:`~danae_lite.commands.reproduce`, :mod:`~danae_lite.commands.leaderboard`  the commands (the files they write)
* :mod:`~danae_lite.cli`  ``python -m danae_lite data|reproduce|leaderboard``: the arguments, and the command they ask for
"""
from ._version import __version__
