"""Gaussian-particle-filter multi-target tracking on FLS images (FLS paper §4-§5): small modules, one role each.

* :mod:`.config` settings, :mod:`.gaussian` the GPF of Kotecha and Djuric (eqs. 5-12),
* :mod:`.cues` per-particle window features and their distance to a template (eq. 13),
* :mod:`.fusion` multiplicative, weighted and adaptive fusion (eqs. 14-18), :mod:`.fuzzy` the
  weights of Tables 8-9,
* :mod:`.track` the track record, :mod:`.management` births, lost tracks, templates (§4.2.3),
* :mod:`.tracker` the tracker that wires them together, :mod:`.sir` and :mod:`.ekf` the
  baselines of Figure 13.
"""
from sonar_tracking.core.gpf.config import FUSION_MODES, GpfConfig
from sonar_tracking.core.gpf.cues import CUE_SPECS, CueModel
from sonar_tracking.core.gpf.ekf import EkfConfig, EkfTracker
from sonar_tracking.core.gpf.fusion import MF, WF, fuse
from sonar_tracking.core.gpf.fuzzy import fuzzy_weights
from sonar_tracking.core.gpf.track import GpfTrack, tracks_to_records
from sonar_tracking.core.gpf.tracker import GpfInputError, GpfTracker, StepReport

__all__ = ['FUSION_MODES', 'GpfConfig', 'CUE_SPECS', 'CueModel', 'EkfConfig', 'EkfTracker', 'MF', 'WF', 'fuse',
           'fuzzy_weights', 'GpfTrack', 'tracks_to_records', 'GpfInputError', 'GpfTracker', 'StepReport']
