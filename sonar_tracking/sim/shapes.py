"""Target shapes of the FLS paper's tank trials (§3.4): pontoon, cube, triangular prism,
reflector, sphere, plus an ideal point; and the imaging-sonar targets: a diver, a vehicle and a fish.

A shape is a set of scatterers in the body frame (x along the body heading). Flat faces are rows
of facet scatterers whose echo is mostly specular, ``cos(incidence) ** n``, with a diffuse share
``~cos(incidence)``, and vanishes when the face looks away; corners are weak, broad scatterers. So a
cube seen face-on gives one bright line, but seen corner-on gives a few separate weak spots: one
target, several unconnected regions (FLS paper §2, drawback 2). The sphere's steep, outward-facing
facets reduce to the specular point facing the sonar. Weights are normalised so the strongest
aspect returns a total of 1.

``height`` is how far the object stands above what lies behind it, for the acoustic shadow an
imaging sonar draws (:mod:`.imaging`); 0 casts none.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

__all__ = ['Shape', 'SHAPES', 'shape', 'DIFFUSE']

#: Share of a facet's echo scattered diffusely (Lambert, ~cos) by surface roughness; the rest is
#: specular (~cos ** n).
DIFFUSE = 0.05


@dataclass(frozen=True, eq=False)
class Shape:
    """Scatterers of a target in its body frame."""

    name: str
    points: np.ndarray     # (K, 2) positions [m]
    normals: np.ndarray    # (K, 2) unit outward normals; (0, 0) = isotropic
    weights: np.ndarray    # (K,) relative strengths
    exponents: np.ndarray  # (K,) facet directivity exponents
    extent: float          # largest dimension [m]
    height: float = dataclasses.field(default=0.0, kw_only=True)  # shadow-casting height [m]

    def response(self, toward_sonar: np.ndarray) -> np.ndarray:
        """Echo strength of every scatterer for unit directions toward the sonar, body frame.

        ``toward_sonar`` has shape (..., K, 2) (one direction per scatterer) or (..., 1, 2) (far
        field: one direction for all); the result has shape (..., K).
        """
        cos = np.clip(np.sum(toward_sonar * self.normals, axis=-1), 0.0, None)
        iso = np.all(self.normals == 0.0, axis=1)
        facet = (1.0 - DIFFUSE) * cos ** self.exponents + DIFFUSE * cos
        return self.weights * np.where(iso, 1.0, facet)


def _normalised(name: str, points, normals, weights, exponents, extent: float, height: float = 0.0) -> Shape:
    pts, nrm = np.asarray(points, float), np.asarray(normals, float)
    w, e = np.asarray(weights, float), np.asarray(exponents, float)
    raw = Shape(name, pts, nrm, w, e, extent)
    angles = np.linspace(0.0, 2 * math.pi, 720, endpoint=False)
    u = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    peak = raw.response(u[:, None, :]).sum(axis=1).max()
    return Shape(name, pts, nrm, w / peak, e, extent, height=height)


def _polygon(name: str, vertices, face_exponent: float, corner_weight: float, spacing: float = 0.05) -> Shape:
    """Facet scatterers along each edge of a convex polygon (counter-clockwise vertices) plus corners."""
    v = np.asarray(vertices, float)
    v = v - v.mean(axis=0)
    points, normals, weights, exps = [], [], [], []
    n = len(v)
    for i in range(n):
        a, b = v[i], v[(i + 1) % n]
        edge = b - a
        length = float(np.hypot(*edge))
        normal = np.array([edge[1], -edge[0]]) / length  # outward for CCW vertices
        k = max(2, int(round(length / spacing)))
        for s in (np.arange(k) + 0.5) / k:
            points.append(a + s * edge)
            normals.append(normal)
            weights.append(length / k)
            exps.append(face_exponent)
    for i in range(n):
        prev_edge, next_edge = v[i] - v[i - 1], v[(i + 1) % n] - v[i]
        bis = np.array([prev_edge[1], -prev_edge[0]]) / np.hypot(*prev_edge) + \
            np.array([next_edge[1], -next_edge[0]]) / np.hypot(*next_edge)
        points.append(v[i])
        normals.append(bis / np.hypot(*bis))
        weights.append(corner_weight)
        exps.append(1.0)
    extent = float(max(np.hypot(*(p - q)) for p in v for q in v))
    return _normalised(name, points, normals, weights, exps, extent)


def _rectangle(name: str, length: float, width: float, face_exponent: float, corner_weight: float) -> Shape:
    h, w = length / 2, width / 2
    return _polygon(name, [(-h, -w), (h, -w), (h, w), (-h, w)], face_exponent, corner_weight)


def _sphere(radius: float, n: int = 24) -> Shape:
    a = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    u = np.stack([np.cos(a), np.sin(a)], axis=1)
    return _normalised('sphere', radius * u, u, np.ones(n), np.full(n, 40.0), 2 * radius)


def _reflector(size: float) -> Shape:
    # A corner reflector: strong over a wide cone around its axis, weak isotropic elsewhere.
    return _normalised('reflector', [(0.0, 0.0), (0.0, 0.0)], [(1.0, 0.0), (0.0, 0.0)], [1.0, 0.3],
                       [1.5, 1.0], size)


def _triangle(side: float) -> Shape:
    r = side / math.sqrt(3.0)
    verts = [(r * math.cos(a), r * math.sin(a)) for a in (0.0, 2 * math.pi / 3, 4 * math.pi / 3)]
    return _polygon('prism', verts, face_exponent=12.0, corner_weight=0.03)


def _diver() -> Shape:
    # A swimming diver seen from above, 1.8 m head to fins and 0.5 m across the arms: isotropic
    # scatterers of a soft body, the cylinder and valve of the tank strongest, the fins weakest.
    parts = [((0.80, 0.00), 0.5),                                  # head
             ((0.50, 0.22), 0.3), ((0.50, -0.22), 0.3),            # arms / shoulders
             ((0.45, 0.00), 1.0), ((0.20, 0.00), 1.0),             # tank
             ((0.05, 0.00), 0.6),                                  # hips, weight belt
             ((-0.35, 0.12), 0.3), ((-0.35, -0.12), 0.3),          # knees
             ((-0.70, 0.12), 0.2), ((-0.70, -0.12), 0.2),          # ankles
             ((-0.90, 0.15), 0.15), ((-0.90, -0.15), 0.15)]        # fins
    pts = [p for p, _ in parts]
    return _normalised('diver', pts, np.zeros((len(pts), 2)), [w for _, w in parts], np.ones(len(pts)), 1.8,
                       height=0.4)


def _vehicle(length: float = 3.5, width: float = 0.6) -> Shape:
    # A work-class ROV or AUV hull: a box whose flanks flash at broadside (specular facets), plus
    # isotropic nose, thrusters and skids that keep it bright from any aspect.
    hull = _rectangle('vehicle', length, width, face_exponent=8.0, corner_weight=0.05)
    h, w = length / 2, width / 2
    extra = [((h, 0.0), 0.3), ((-h, w), 0.25), ((-h, -w), 0.25), ((0.0, w), 0.15), ((0.0, -w), 0.15)]
    pts = np.concatenate([hull.points, [p for p, _ in extra]])
    nrm = np.concatenate([hull.normals, np.zeros((len(extra), 2))])
    wts = np.concatenate([hull.weights, [v for _, v in extra]])
    exps = np.concatenate([hull.exponents, np.ones(len(extra))])
    return _normalised('vehicle', pts, nrm, wts, exps, float(math.hypot(length, width)), height=0.6)


SHAPES: dict[str, Shape] = {
    'pontoon': _rectangle('pontoon', 1.0, 0.4, face_exponent=20.0, corner_weight=0.02),
    'cube': _rectangle('cube', 0.5, 0.5, face_exponent=12.0, corner_weight=0.04),
    'prism': _triangle(0.6),
    'reflector': _reflector(0.4),
    'sphere': _sphere(0.25),
    'point': _normalised('point', [(0.0, 0.0)], [(0.0, 0.0)], [1.0], [1.0], 0.0),
    'diver': _diver(),
    'vehicle': _vehicle(),
    # A fish of about 30 cm: one isotropic scatterer (its swim bladder), too small to cast a shadow.
    'fish': _normalised('fish', [(0.0, 0.0)], [(0.0, 0.0)], [1.0], [1.0], 0.3),
}


def shape(name: str) -> Shape:
    """The named shape; raises ValueError listing the known names."""
    try:
        return SHAPES[name]
    except KeyError:
        raise ValueError(f'unknown target shape {name!r}; known: {sorted(SHAPES)}') from None
