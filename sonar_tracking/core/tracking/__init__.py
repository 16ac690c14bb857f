"""IMM-IPDA multi-target tracking (ESC paper §2.4): small modules, one role each.

* :mod:`.motion` motion models CV and CTR (eqs. 3-4), :mod:`.noise` process noise,
* :mod:`.markov` mode transition matrix (eq. 21) and existence chain (eqs. 24, 40),
* :mod:`.gaussian` mixture moment matching, :mod:`.imm` interaction and combination
  (eqs. 17-20, 41-42), :mod:`.kalman` prediction (eqs. 22-23),
* :mod:`.gating` gates and likelihoods (eqs. 25-28), :mod:`.ipda` the update (eqs. 28-40),
* :mod:`.measurements` input checks, :mod:`.management` initiation, confirmation, termination,
* :mod:`.coverage` the area a scan covered, :mod:`.config` settings, :mod:`.tracker` the tracker
  that wires them together.

Array layout. The per-track arrays of :mod:`.imm`, :mod:`.kalman`, :mod:`.gaussian`,
:mod:`.ipda` and the per-pair arrays of :mod:`.gating` are component-major with tracks (or
pairs) last: ``x (n, M, T)``, ``P (n, n, M, T)``, ``mu (M, T)`` for T tracks and M modes. numpy,
and the compiled kernels (:mod:`sonar_tracking.core.jit`) where their innermost loop runs over the
tracks, then work along the long axis. Motion models return ordinary ``(n, n)`` matrices, measurements come
in as ``z (N, d)``, ``R (N, d, d)``, and :meth:`.ImmIpdaTracker.estimates` /
:meth:`.ImmIpdaTracker.mode_states` give tracks-first copies.
"""
from sonar_tracking.core.tracking.config import MODE_NAMES, TrackerConfig
from sonar_tracking.core.tracking.coverage import Coverage
from sonar_tracking.core.tracking.errors import TrackingError, TrackingInputError
from sonar_tracking.core.tracking.gating import candidate_pairs, gate_probability, gate_threshold, innovations
from sonar_tracking.core.tracking.gaussian import moment_match
from sonar_tracking.core.tracking.imm import combine, interaction
from sonar_tracking.core.tracking.ipda import ipda_update
from sonar_tracking.core.tracking.kalman import predict
from sonar_tracking.core.tracking.management import initial_covariance
from sonar_tracking.core.tracking.markov import mode_transition_matrix, predict_existence, update_existence
from sonar_tracking.core.tracking.measurements import Rejection, check_measurements
from sonar_tracking.core.tracking.motion import ConstantTurn, ConstantVelocity, MotionModel, position_matrix
from sonar_tracking.core.tracking.noise import white_noise_acceleration
from sonar_tracking.core.tracking.tracker import ImmIpdaTracker, Mode, StepReport, modes_from_config

__all__ = ['MODE_NAMES', 'TrackerConfig', 'Coverage', 'TrackingError', 'TrackingInputError', 'candidate_pairs',
           'gate_probability', 'gate_threshold', 'innovations', 'moment_match', 'combine', 'interaction',
           'ipda_update', 'predict', 'initial_covariance', 'mode_transition_matrix', 'predict_existence',
           'update_existence', 'Rejection', 'check_measurements', 'ConstantTurn', 'ConstantVelocity',
           'MotionModel', 'position_matrix', 'white_noise_acceleration', 'ImmIpdaTracker', 'Mode',
           'StepReport', 'modes_from_config']
