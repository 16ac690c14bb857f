"""Fuzzy weights a_i of the weighted fusion (eq. 14): the procedure of Table 8 with the rules of Table 9.

Table 8: (1) ``f_else,i``, the mean reliability of the other cues; (2) a fuzzy controller with the
inputs ``1/Delta_i`` and ``f_else,i`` and the rules of Table 9; (3) its output ``b_i``;
(4) ``a_i = b_i / sum_j b_j``. The paper gives neither the membership functions nor the
defuzzification; ours:

* **Inputs, normalised.** Reliabilities (``1/Delta_i``, which :mod:`.fusion` takes relative to
  the particles' own spread) span decades and only mean something against the cue's threshold
  ``T_i`` of eq. (18), so each is taken as the ratio ``r_i = (1/Delta_i) / T_i`` and put
  on the universe ``u = clip(log2(r) / 2, -1, 1)``: ``u = 0`` at the switching point of eq. (18),
  ``+-1`` at four times above or below it. ``f_else,i`` is the mean of ``r_j`` over the other cues
  (Table 8 divides the sum by m; we divide by the m - 1 terms summed, so a cue set of equal
  reliabilities gives ``f_else,i = r_i``), normalised the same way.
* **Membership functions.** Five triangles NB, NS, ZE, PS, PB with peaks at ``u = -1, -0.5, 0,
  0.5, 1``, each falling to zero at its neighbours' peaks; NB and PB stay at 1 beyond ``-1`` and
  ``+1`` (shoulders). They form a partition of unity: every ``u`` belongs to at most two sets
  with memberships summing to 1.
* **Rules and defuzzification.** Table 9 gives, for each pair (``f_else`` set, ``1/Delta_i`` set),
  a consequent level 1..5 (rows ``f_else`` NB..PB, columns ``1/Delta_i`` NB..PB): a cue better
  than the others gets a high level, a cue worse than the others a low one, 3 when they are alike.
  Each rule fires with the product of its two memberships and the output level is the
  firing-weighted mean of the rule levels (zero-order Sugeno); with a partition of unity this
  interpolates Table 9 bilinearly between the set peaks, so the level is continuous in both
  inputs and stays within 1..5.
* **Output scale.** A weight is a ratio, so the levels are read on a geometric scale:
  ``b_i = 10 ** (level - 3)``, each level ten times the weight of the one below. With the levels
  themselves as weights (1 to 5) a degenerated cue would keep a fifth of a good cue's weight, and
  since a degenerated cue's likelihood is nearly flat over the particles, that share alone would
  spread the fused likelihood over the whole particle cloud: eq. (14) would not locate anything.
  Every ``a_i`` stays positive.
"""
from __future__ import annotations

import numpy as np

__all__ = ['RULES', 'LEVEL_RATIO', 'memberships', 'universe', 'fuzzy_levels', 'fuzzy_weights']

#: Table 9: consequent level of each rule; rows f_else NB, NS, ZE, PS, PB; columns 1/Delta_i NB..PB.
RULES = np.array([[3, 4, 4, 5, 5],
                  [2, 3, 4, 4, 5],
                  [2, 2, 3, 4, 4],
                  [1, 2, 2, 3, 4],
                  [1, 1, 2, 2, 3]], dtype=np.float64)

_PEAKS = np.array([-1.0, -0.5, 0.0, 0.5, 1.0])


def universe(ratio: np.ndarray) -> np.ndarray:
    """The normalised input ``clip(log2(ratio) / 2, -1, 1)`` of a reliability ratio ``(1/Delta)/T``."""
    r = np.maximum(np.asarray(ratio, dtype=np.float64), 1e-300)
    return np.clip(np.log2(r) / 2.0, -1.0, 1.0)


def memberships(u: np.ndarray) -> np.ndarray:
    """Memberships ``(..., 5)`` of NB, NS, ZE, PS, PB at normalised inputs ``u`` in ``[-1, 1]``."""
    u = np.asarray(u, dtype=np.float64)
    return np.clip(1.0 - np.abs(u[..., None] - _PEAKS) / 0.5, 0.0, 1.0)


def fuzzy_levels(own: np.ndarray, others: np.ndarray) -> np.ndarray:
    """Controller output level (1..5, Table 8 step 3) for reliability ratios of a cue (``own``) and
    the mean ratio of the other cues (``others``), arrays of one shape."""
    mu_own = memberships(universe(own))
    mu_else = memberships(universe(others))
    fire = mu_else[..., :, None] * mu_own[..., None, :]
    return np.sum(fire * RULES, axis=(-2, -1)) / np.sum(fire, axis=(-2, -1))


#: Weight ratio between consecutive output levels (module docstring).
LEVEL_RATIO = 10.0


def fuzzy_weights(inverse_spread: np.ndarray, thresholds: np.ndarray) -> np.ndarray:
    """Weights ``a_i`` of eq. (14) (Table 8) from each cue's ``1/Delta_i`` (eq. 17) and ``T_i``.

    Returns ``(m,)`` positive weights summing to 1 (``(..., m)`` for ``inverse_spread (..., m)``);
    one cue gets weight 1.
    """
    inv = np.asarray(inverse_spread, dtype=np.float64)
    m = inv.shape[-1]
    if m == 1:
        return np.ones(inv.shape)
    ratio = inv / np.asarray(thresholds, dtype=np.float64)
    others = (ratio.sum(axis=-1, keepdims=True) - ratio) / (m - 1)
    b = LEVEL_RATIO ** (fuzzy_levels(ratio, others) - 3.0)
    return b / b.sum(axis=-1, keepdims=True)
