"""Wrapper feature selection by sequential forward and backward search, FLS paper §3.2.

Table 4 (SFS): start from the empty set and repeatedly add the feature ``x+ = argmax J(Y_k + x)``;
Table 3 (SBS): start from all features and repeatedly remove ``x- = argmax J(Y_k - x)`` (the
feature whose removal hurts least or helps most). The paper prints the two captions swapped and
writes ``x in Y_k`` for SFS, where the candidates are the features not yet in ``Y_k``; we follow
the text. Both searches run to the end (1..30 features) and record the criterion at every size,
which is the paper's "classification error against the number of features" (Figure 6); the
selected subset is the one of least error (the smallest on ties). Ties between candidates go to
the lower feature number, so a search is deterministic.

The criterion ``J`` is ``1 - error`` of the wrapped classifier, here the GRNN of eq. (4)
(:class:`GrnnWrapper`): trained on one set of regions, its balanced error measured on another.
"""
from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from sonar_tracking.core.fls.grnn import RankScaler, balanced_error, kernel_average

__all__ = ['SelectionResult', 'sfs', 'sbs', 'GrnnWrapper']


@dataclass
class SelectionResult:
    """A search path: ``subsets[k - 1]`` is the subset of ``k`` features and ``errors[k - 1]`` its error."""

    method: str
    subsets: list[tuple[int, ...]] = field(default_factory=list)
    errors: list[float] = field(default_factory=list)

    @property
    def best(self) -> tuple[int, ...]:
        """The subset of least error (the smallest of equals)."""
        return self.subsets[int(np.argmin(self.errors))]

    @property
    def order(self) -> list[int]:
        """Features in order of merit: SFS the order added, SBS the reverse order removed."""
        out = [self.subsets[0][0]]
        for a, b in zip(self.subsets, self.subsets[1:]):
            out.append(next(f for f in b if f not in a))
        return out

    def subset_of(self, k: int) -> tuple[int, ...]:
        return self.subsets[k - 1]


Criterion = Callable[[tuple[int, ...]], float]


def sfs(error: Criterion, features: Sequence[int], max_features: int | None = None) -> SelectionResult:
    """Sequential forward selection (Table 4) minimising ``error(subset)``."""
    remaining = sorted(set(features))
    stop = len(remaining) if max_features is None else min(max_features, len(remaining))
    result = SelectionResult('sfs')
    chosen: tuple[int, ...] = ()
    while len(chosen) < stop:
        scores = [(error(tuple(sorted(chosen + (x,)))), x) for x in remaining]
        best_err, best_x = min(scores)  # ties: the lower feature number
        chosen = tuple(sorted(chosen + (best_x,)))
        remaining.remove(best_x)
        result.subsets.append(chosen)
        result.errors.append(best_err)
    return result


def sbs(error: Criterion, features: Sequence[int], min_features: int = 1) -> SelectionResult:
    """Sequential backward selection (Table 3) minimising ``error(subset)``; the path is returned
    from the smallest subset up, as for SFS."""
    current = tuple(sorted(set(features)))
    subsets, errors = [current], [error(current)]
    while len(current) > max(1, min_features):
        scores = [(error(tuple(f for f in current if f != x)), x) for x in current]
        best_err, worst_x = min(scores)
        current = tuple(f for f in current if f != worst_x)
        subsets.append(current)
        errors.append(best_err)
    return SelectionResult('sbs', subsets[::-1], errors[::-1])


class GrnnWrapper:
    """The wrapper criterion: balanced validation error of a GRNN (eq. 4) on a feature subset.

    Features are numbered 1..d (Table 2 numbering) over the columns of the matrices. Squared
    distances between validation and training samples are kept per feature, so a subset's
    distances are a sum, and a subset one feature away from one already evaluated costs one
    addition (both searches move one feature at a time).
    """

    def __init__(self, x_train: np.ndarray, y_train: np.ndarray, x_val: np.ndarray, y_val: np.ndarray,
                 sigma: float = 0.1, cache: int = 80) -> None:
        scaler = RankScaler().fit(x_train)
        qt, qv = scaler.transform(x_train), scaler.transform(x_val)
        self._dsq = np.ascontiguousarray(((qv[:, None, :] - qt[None, :, :]) ** 2).transpose(2, 0, 1),
                                         dtype=np.float32)
        self.classes, idx = np.unique(np.asarray(y_train), return_inverse=True)
        self._onehot = np.eye(self.classes.size)[idx]
        self.y_val = np.asarray(y_val)
        self.sigma = float(sigma)
        self._cache: OrderedDict[tuple[int, ...], np.ndarray] = OrderedDict()
        self._size = cache
        self.evaluations = 0

    @property
    def n_features(self) -> int:
        return self._dsq.shape[0]

    def _distances(self, key: tuple[int, ...]) -> np.ndarray:
        hit = self._cache.get(key)
        if hit is not None:
            self._cache.move_to_end(key)
            return hit
        d2 = None
        for k, cached in reversed(self._cache.items()):
            if len(k) == len(key) - 1 and set(k) < set(key):
                (extra,) = set(key) - set(k)
                d2 = cached + self._dsq[extra - 1]
                break
            if len(k) == len(key) + 1 and set(k) > set(key):
                (extra,) = set(k) - set(key)
                d2 = cached - self._dsq[extra - 1]
                break
        if d2 is None:
            d2 = self._dsq[[f - 1 for f in key]].sum(axis=0)
        self._cache[key] = d2
        while len(self._cache) > self._size:
            self._cache.popitem(last=False)
        return d2

    def __call__(self, subset: tuple[int, ...]) -> float:
        """Balanced validation error of the GRNN on features ``subset`` (1-based)."""
        key = tuple(sorted(subset))
        if not key or key[0] < 1 or key[-1] > self.n_features:
            raise ValueError(f'subset {subset} must hold feature numbers 1..{self.n_features}')
        self.evaluations += 1
        d2 = np.maximum(self._distances(key), 0.0).astype(np.float64)
        two_s2 = 2.0 * (self.sigma * math.sqrt(len(key) / 6.0)) ** 2
        pred = self.classes[np.argmax(kernel_average(d2, self._onehot, two_s2), axis=1)]
        return balanced_error(self.y_val, pred)
