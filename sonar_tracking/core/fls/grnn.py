"""Generalised regression neural network (Specht) as a region classifier, FLS paper §3.3.

Eq. (4): for training pairs ``(X_i, Y_i)`` and smoothing factor ``sigma``::

    Y(X) = sum_i Y_i exp(-|X - X_i|^2 / (2 sigma^2)) / sum_i exp(-|X - X_i|^2 / (2 sigma^2))

With ``Y_i`` the one-hot vector of sample ``i``'s class, ``Y(X)`` is a kernel estimate of the
class probabilities at ``X``; the predicted class is the largest. Choices where the paper is silent:

* **Feature scaling.** The region features span decades (area, Hu moments of 1e-12) and have
  heavy tails, so a z-score would let a few outliers set every distance. Each feature is mapped
  through its training distribution (mid-rank / n, in [0, 1]) before the Euclidean distance of
  eq. (4): monotone, scale-free and robust (:class:`RankScaler`).
* **Smoothing factor.** ``sigma`` is given relative to the root-mean-square distance between two
  independent points of the scaled space, ``sqrt(d / 6)`` for ``d`` features, so one value suits
  subsets of any size (the wrapper search compares subsets of 1 to 30 features).
* Exponents are shifted by each query's nearest training sample before ``exp`` so a query far
  from all samples still gets the class of its nearest neighbour instead of 0 / 0.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ['GRNN', 'RankScaler', 'balanced_error']


class RankScaler:
    """Maps each feature through its training distribution: mid-rank / n in [0, 1]."""

    def fit(self, x: np.ndarray) -> RankScaler:
        x = _matrix(x, 'training features')
        self.sorted_ = np.sort(x, axis=0)
        return self

    def transform(self, x: np.ndarray) -> np.ndarray:
        x = _matrix(x, 'features')
        s = self.sorted_
        if x.shape[1] != s.shape[1]:
            raise ValueError(f'features have {x.shape[1]} columns, the scaler was fitted on {s.shape[1]}')
        out = np.empty(x.shape)
        for k in range(x.shape[1]):  # one searchsorted per feature (30 at most), vectorised over samples
            lo = np.searchsorted(s[:, k], x[:, k], side='left')
            hi = np.searchsorted(s[:, k], x[:, k], side='right')
            out[:, k] = 0.5 * (lo + hi) / s.shape[0]
        return out


def _matrix(x: np.ndarray, what: str) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 2 or a.shape[0] == 0:
        raise ValueError(f'{what} must be a non-empty 2-D array (samples x features), got shape {a.shape}')
    bad = ~np.isfinite(a)
    if bad.any():
        cols = sorted(set(np.nonzero(bad)[1].tolist()))
        raise ValueError(f'{what} have non-finite values in columns {cols}; drop those samples first')
    return a


class GRNN:
    """GRNN classifier of eq. (4) on rank-scaled features (see module docstring)."""

    def __init__(self, sigma: float = 0.1) -> None:
        if not (math.isfinite(sigma) and sigma > 0):
            raise ValueError(f'GRNN sigma = {sigma} must be a finite number > 0')
        self.sigma = float(sigma)

    def fit(self, x: np.ndarray, y: np.ndarray) -> GRNN:
        """Store the training samples (one pass, no iteration: the network is its samples)."""
        x = _matrix(x, 'training features')
        y = np.asarray(y)
        if y.shape != (x.shape[0],):
            raise ValueError(f'{x.shape[0]} samples but {y.shape} labels')
        self.scaler_ = RankScaler().fit(x)
        self.x_ = self.scaler_.transform(x)
        self.classes_, idx = np.unique(y, return_inverse=True)
        self.onehot_ = np.eye(self.classes_.size)[idx]
        return self

    def bandwidth(self, n_features: int) -> float:
        """The absolute smoothing factor for ``n_features`` scaled features."""
        return self.sigma * math.sqrt(n_features / 6.0)

    def predict_proba(self, x: np.ndarray, batch: int = 1024) -> np.ndarray:
        """Eq. (4) with one-hot targets: class probabilities ``(samples, classes)``."""
        q = self.scaler_.transform(x)
        s2 = 2.0 * self.bandwidth(q.shape[1]) ** 2
        out = np.empty((q.shape[0], self.classes_.size))
        for i in range(0, q.shape[0], batch):
            d2 = _sq_distances(q[i:i + batch], self.x_)
            out[i:i + batch] = kernel_average(d2, self.onehot_, s2)
        return out

    def predict(self, x: np.ndarray) -> np.ndarray:
        """The most probable class of each sample."""
        return self.classes_[np.argmax(self.predict_proba(x), axis=1)]


def _sq_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d2 = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    return np.maximum(d2, 0.0)


def kernel_average(d2: np.ndarray, targets: np.ndarray, two_sigma2: float) -> np.ndarray:
    """Eq. (4) for squared distances ``d2 (queries, samples)`` and sample targets ``(samples, k)``."""
    w = np.exp(-(d2 - d2.min(axis=1, keepdims=True)) / two_sigma2)
    return (w @ targets) / w.sum(axis=1, keepdims=True)


def balanced_error(y_true: np.ndarray, y_pred: np.ndarray) -> float:
    """Mean over the true classes of the fraction misclassified (so a common class such as
    clutter does not decide the result alone)."""
    y_true, y_pred = np.asarray(y_true), np.asarray(y_pred)
    classes = np.unique(y_true)
    return float(np.mean([np.mean(y_pred[y_true == c] != c) for c in classes]))
