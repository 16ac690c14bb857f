"""Static-structure rejection for both front ends: walls, seabed bands, piles, hulls, ringdown.

Real sonar scenes are dominated by static structure: bright, extended, always there. Neither paper
treats it (the ESC paper's clutter is Poisson in open water, the FLS paper's tank is empty apart from
its targets), so this module does what sonar trackers do (a clutter map of persistent echoes, and size
gates on extended returns), in one place for ``active_detector`` and ``fls_features``. Both rules
judge a *connected echo*: a connected group of above-threshold cells in the detector (its
8-connected component, see :mod:`.detection.cells`), a grown region in the FLS. Everything that
echo produced is dropped when it is structure.

**1. Persistent-echo background** (a clutter map of echo frequency, learnt online). Every map cell
keeps a discounted frequency of echo over its looks::

    S <- S exp(-dt / T) + z,    W <- W exp(-dt / T) + 1,    p = S / W

``z = 1`` when the cell echoed in this look (detector: a cell above the current threshold; FLS: a
pixel above the region growth level ``segment.grow_db``), ``dt`` the time since the cell's
previous look and ``T = time_constant``. Until ``T`` has passed ``p`` is the plain fraction of
looks with echo; after that it is an exponential average over about ``T`` seconds (the
discounting is in time, so a sonar that looks at a cell every 0.1 s and one that looks every 5 s
forget at the same rate). ``e = p min(age, T)`` is then the time the cell has echoed within that
window (``age`` = time since its first look). A cell is *persistent* when it echoed in at least
a fraction ``persistence`` of its looks **and** for at least ``min_echo_time`` seconds in all::

    p >= persistence    and    p min(age, T) >= min_echo_time

A cell not looked at for ``3 T`` starts afresh, and a cell within ``margin`` map cells of a
persistent one counts as persistent too (the flickering edges and broken ends of structure). An
echo with at least ``veto_fraction`` of its cells on persistent cells is vetoed. The map learns
from every above-level cell, vetoed or not, after the veto decision for the look.

Which moving targets are safe: a target whose echo is ``L`` long along its track, moving at ``v``,
keeps a map cell of size ``c`` echoing for ``d = (L + c) / v`` seconds, so that cell's echo time is
at most ``d``: a target is never learnt while ``d < min_echo_time``, i.e. while it moves faster than
``(L + c) / min_echo_time``. With the default 7.5 s: an echo 2 m long with its cell is safe from
0.27 m/s, a target at 0.5 m/s with ``L + c`` up to 3.75 m, at 1 m/s up to 7.5 m; the ESC paper's
harbour sonar (17 m cells, boats at 12 m/s, dwell about 3 s) wants 3 s. Static structure that
echoes in every look is vetoed ``min_echo_time`` after it is first seen; structure echoing in a
fraction ``q >= persistence`` of looks after ``min_echo_time / q``. The protection of moving targets
is the echo time alone, so ``persistence`` can be low (0.2: the flickering edges of walls and
seabed bands, cells echoing in a fifth of the looks, are structure too, while clutter cells echo in
well under 1 %). A target that stops is learnt after about ``T ln(1 / (1 - persistence)) = 40 s``
(defaults) and then vetoed: the price of any clutter map, and the reason ``T`` is a setting. Until
then the shape gates below are the only rule, and they work from the first look.

Where the map lives (``map``). The *sensor* map keeps one cell per range bin and beam bearing
(the polar resolution cells: exact for a static sonar, fine near the sonar where a Cartesian grid
would be coarse; beams kept by bearing over one turn, so a scanning head's sweeps fall on the same
cells). It learns what is static in the sensor frame: everything, for a static sonar, and for a
moving one the seabed band (the bottom at the range where the beams reach it) and ringdown. The
*world* map is a square grid of ``world_cell`` metres in the world frame, in a window of
``2 range_max`` around the sonar that follows it (whole cells; history kept where windows overlap),
and learns what is static in the world when the sonar moves (walls, piles, a moored hull).
``auto`` keeps the sensor map always and adds the world map once the pose moves by half a range
bin or half a beam step from where it was first given; a cell is persistent if it is in either
map. ``sensor`` or ``world`` use one map only. Each map is held to ``max_map_cells`` by coarser
cells (range bins joined in the sensor map, a larger ``world_cell``). The FLS pipeline learns on
a grid in its image frame (the sensor frame for a static sonar, the world frame for a moving one),
once per completed sweep, so each pixel is one look per sweep.

**2. Shape gates in metres** (``max_length``, ``max_width``, ``max_area``, ``elongated_length``,
``max_aspect``). An echo's length and width are ``sqrt(12 lambda)`` of the eigenvalues ``lambda`` of
the second moments of its cells, each cell counted with its own footprint (range bin by beam arc,
or pixel): the sides of the rectangle with the same moments, so a single cell measures as its
footprint. Its area is the sum of its cells' footprints. An echo is structure when it is longer
than ``max_length``, wider (its narrow side) than ``max_width`` or larger than ``max_area``, or when
it is elongated: at least ``elongated_length`` long and ``max_aspect`` times longer than wide (a
wall face, a seabed band, a pile row). Targets of the papers are 0.3-3 m, so e.g. 6 m, 3 m, 10 m^2,
3 m at aspect 4 separate them from walls and bands. 0 switches a gate off. A target touching
structure is one connected echo with it and is dropped with it (a clutter map masks what is on
it); the measured behaviour and the choices are in ``docs/algorithms/structure_rejection.md``.

Everything is off by default (``enabled``), so both pipelines reproduce the papers unless asked.

Cost per look. An imaging sonar looks at every cell of its fan every frame (512 x 1000 cells at
20 Hz), so the looks avoid temporaries over the whole fan: the sensor map keeps one weight ``W`` per
beam column (every cell of a column is looked at together, so they share it) and updates ``S`` in
place; the world map places the sector's cells in its grid and applies the rule to the cells seen in
compiled loops, with ``exp`` taken by numpy once per distinct previous look time; its storage wraps
around, so a window that follows the sonar by a cell clears a row or column of it and copies
nothing. The arithmetic is the rule's, operation for operation, in float32 like the maps.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.jit import kernel
from sonar_tracking.core.sector import SectorGeometry

__all__ = ['WarmUp', 'StructureConfig', 'echo_shapes', 'is_structure_shape', 'PolarBackground', 'GridBackground',
           'SectorBackground', 'vetoed_groups']

_FORGET = 3.0          # a cell unseen for this many time constants starts afresh (5 % weight left)
_LAST_LOOKS = 8192     # distinct previous look times a compiled world-map look handles (more: the array code)


@dataclass(frozen=True)
class StructureConfig(Config):
    """Static-structure rejection: persistent-echo background and shape gates (see core/structure.py)."""

    enabled: bool = setting(False, 'reject echoes of static structure (walls, seabed bands, piles): the '
                            'persistent-echo veto and the shape gates below')
    time_constant: float = setting(180.0, 'memory of the persistent-echo background: echo frequencies are averaged '
                                   'over about this long', unit='s', low=1.0, high=1e6)
    persistence: float = setting(0.2, 'a map cell that echoed in at least this fraction of its recent looks is '
                                 'static structure; 1 = switch the persistence veto off', low=0.05, high=1.0)
    min_echo_time: float = setting(7.5, 'a map cell is persistent only after echoing this long in all; moving '
                                   'targets are safe while (echo length + cell) / speed is shorter', unit='s',
                                   low=0.0, high=1e6)
    warmup: bool = setting(True, 'output no detections or regions until the background has learnt for '
                           'min_echo_time after a start or reset: structure in view from the first ping cannot be '
                           'told from a target before that')
    veto_fraction: float = setting(0.5, 'an echo is vetoed when at least this fraction of its cells lie on '
                                   'persistent map cells', low=0.0, low_open=True, high=1.0)
    margin: int = setting(1, 'a cell within this many map cells of a persistent cell counts as persistent (the '
                          'flickering edges of structure)', low=0, high=5)
    map: str = setting('auto', "where the background is learnt: 'sensor' (polar cells of the sensor: ringdown, "
                       "seabed bands, and all structure of a static sonar), 'world' (a grid in the world frame that "
                       "follows a moving sonar: walls, piles) or 'auto' (sensor, and world too once the pose "
                       'changes). The FLS pipeline learns on its image grid', choices=('auto', 'sensor', 'world'))
    world_cell: float = setting(0.0, 'cell size of the world-frame map (and of the FLS image background); 0 = the '
                                'sensor cell at mid range (at least an image pixel)', unit='m', low=0.0, high=1e4)
    max_map_cells: int = setting(2_000_000, 'memory bound of each background map (sensor map 4 bytes a cell, world '
                                 'map 24); a sonar with more cells gets coarser map cells', low=1000,
                                 high=50_000_000, read_only=True)
    max_length: float = setting(0.0, 'echoes longer than this are structure; 0 = no limit', unit='m',
                                low=0.0, high=1e5)
    max_width: float = setting(0.0, 'echoes whose narrow side is wider than this are structure; 0 = no limit',
                               unit='m', low=0.0, high=1e5)
    max_area: float = setting(0.0, 'echoes larger than this are structure; 0 = no limit', unit='m^2',
                              low=0.0, high=1e9)
    elongated_length: float = setting(0.0, 'echoes at least this long and max_aspect times longer than wide are '
                                      'walls or seabed bands; 0 = off', unit='m', low=0.0, high=1e5)
    max_aspect: float = setting(4.0, 'length / width from which an echo at least elongated_length long is a wall '
                                'or band', low=1.0, high=1e4)

    def validate(self) -> None:
        if self.max_length and self.elongated_length >= self.max_length:
            raise ConfigError(f'elongated_length = {self.elongated_length} m would never act: echoes longer than '
                              f'max_length = {self.max_length} m are rejected already; make it shorter or 0')
        if self.enabled and not self.shape_gates and not self.persistence_veto:
            raise ConfigError('structure.enabled with persistence = 1 and every shape gate 0 rejects nothing; lower '
                              'persistence or set max_length, max_width, max_area or elongated_length')
        if self.max_length and self.max_width and self.max_width >= self.max_length:
            raise ConfigError(f'max_width = {self.max_width} m would never act: an echo is never wider than long '
                              f'and max_length = {self.max_length} m; make it smaller or 0')

    @property
    def shape_gates(self) -> bool:
        """Whether any shape gate is on."""
        return bool(self.max_length or self.max_width or self.max_area or self.elongated_length)

    @property
    def persistence_veto(self) -> bool:
        """Whether the persistent-echo veto is on (``persistence < 1``)."""
        return self.persistence < 1.0


# -- shapes ---------------------------------------------------------------------------------------

def echo_shapes(x: np.ndarray, y: np.ndarray, labels: np.ndarray, n: int, var_xx: np.ndarray | float,
                var_xy: np.ndarray | float, var_yy: np.ndarray | float,
                cell_area: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Length, width [m] and area [m^2] of ``n`` echoes from their cells (see module docstring).

    ``x, y`` cell centres [m] and ``labels`` the echo ``0..n-1`` of each cell; ``var_*`` each cell's
    own footprint moments (``side^2 / 12``) and ``cell_area`` its area, per cell or one for all.
    """
    labels = np.asarray(labels, dtype=np.intp)
    if n == 0:
        z = np.zeros(0)
        return z, z, z
    cnt = np.bincount(labels, minlength=n).astype(float)
    cnt = np.maximum(cnt, 1.0)

    def mean(v) -> np.ndarray:
        v = np.broadcast_to(np.asarray(v, dtype=float), labels.shape)
        return np.bincount(labels, weights=v, minlength=n) / cnt
    # Centre on each echo's first cell so large coordinates do not cancel.
    first = np.full(n, -1, np.intp)
    first[labels[::-1]] = np.arange(len(labels))[::-1]
    dx = np.asarray(x, float) - np.asarray(x, float)[first][labels]
    dy = np.asarray(y, float) - np.asarray(y, float)[first][labels]
    mx, my = mean(dx), mean(dy)
    cxx = mean(dx * dx) - mx * mx + mean(var_xx)
    cyy = mean(dy * dy) - my * my + mean(var_yy)
    cxy = mean(dx * dy) - mx * my + mean(var_xy)
    half = 0.5 * (cxx + cyy)
    root = np.sqrt(np.maximum(0.25 * (cxx - cyy) ** 2 + cxy * cxy, 0.0))
    length = np.sqrt(12.0 * np.maximum(half + root, 0.0))
    width = np.sqrt(12.0 * np.maximum(half - root, 0.0))
    area = mean(cell_area) * cnt
    return length, width, area


def is_structure_shape(length: np.ndarray, width: np.ndarray, area: np.ndarray,
                       config: StructureConfig) -> np.ndarray:
    """The shape gates: True where an echo is too long, too wide, too large or elongated."""
    c = config
    out = np.zeros(np.shape(length), bool)
    if c.max_length:
        out |= length > c.max_length
    if c.max_width:
        out |= width > c.max_width
    if c.max_area:
        out |= area > c.max_area
    if c.elongated_length:
        out |= (length >= c.elongated_length) & (length >= c.max_aspect * width)
    return out


def vetoed_groups(labels: np.ndarray, n: int, on_persistent: np.ndarray, veto_fraction: float) -> np.ndarray:
    """True for echoes ``0..n-1`` with at least ``veto_fraction`` of their cells persistent."""
    labels = np.asarray(labels, dtype=np.intp)
    cnt = np.bincount(labels, minlength=n)
    hit = np.bincount(labels, weights=np.asarray(on_persistent, dtype=float), minlength=n)
    return (cnt > 0) & (hit >= veto_fraction * cnt - 1e-9)


# -- the echo-frequency rule ------------------------------------------------------------------------

def _persistent(s: np.ndarray, w: np.ndarray, age: np.ndarray, idle: np.ndarray, config: StructureConfig) -> np.ndarray:
    """The persistence test on map cells (module docstring, rule 1)."""
    c = config
    p = s / np.maximum(w, 1e-30)
    return ((w > 0) & (p >= c.persistence) & (p * np.minimum(age, c.time_constant) >= c.min_echo_time)
            & (idle <= _FORGET * c.time_constant))


def _decay(t_last: np.ndarray, t_first: np.ndarray, c: np.ndarray, t: float, time_constant: float) -> np.ndarray:
    """The factor ``exp(-dt / T)`` that ``S`` and ``W`` of the cells (or columns) ``c`` keep at a look at
    time ``t`` (0 for a first look, or one after ``3 T`` unseen); records the look's time."""
    dt = np.maximum(t - t_last[c], 0.0)
    fresh = np.isnan(t_first[c]) | (dt > _FORGET * time_constant)
    t_first[c] = np.where(fresh, t, t_first[c])
    t_last[c] = t
    return np.where(fresh, 0.0, np.exp(-dt / time_constant)).astype(np.float32)


class PolarBackground:
    """Echo frequency per sensor-frame polar cell: range bin x beam bearing (a static sonar).

    Beams are kept by bearing on a ring of one turn, so a scanning head's sectors fall on the same
    cells every sweep; only bearings that were looked at take memory. A map cell is ``bins_per_cell``
    range bins: 1 unless the bearings the sonar covers (one turn for a scanning head, its sector
    for one that forms all beams at once) times the range bins exceed ``max_map_cells``. A change of
    range bins or beam step starts a new map.
    """

    def __init__(self, config: StructureConfig) -> None:
        self.config = config
        self.reset()

    def reset(self) -> None:
        """Forget everything."""
        self._key: tuple | None = None
        self.columns = 0
        self.bins_per_cell = 1

    def _start(self, g: SectorGeometry) -> None:
        self._key = (g.angle_increment, g.n_bins, g.range_min, g.range_max)
        self._ring = max(1, int(round(2.0 * math.pi / g.angle_increment)))
        beams = self._ring if g.ping_period != 0.0 else min(self._ring, g.n_beams)
        self.bins_per_cell = max(1, math.ceil(g.n_bins * beams / self.config.max_map_cells))
        self._rows = math.ceil(g.n_bins / self.bins_per_cell)
        self._ref = g.angle_min
        self._col = np.full(self._ring, -1, np.int64)    # ring slot -> column of the arrays below
        self._s = np.zeros((self._rows, 0), np.float32)
        self._w = np.zeros(0, np.float32)                # per column: its cells are looked at together
        self._t_last = np.zeros(0)
        self._t_first = np.zeros(0)
        self.columns = 0

    def _matches(self, g: SectorGeometry) -> bool:
        key = (g.angle_increment, g.n_bins, g.range_min, g.range_max)
        # numpy's isclose test (rtol 1e-9, atol 1e-12) on four numbers, without its per-call cost
        return self._key is not None and all(a == b or abs(a - b) <= 1e-12 + 1e-9 * abs(b)
                                             for a, b in zip(key, self._key))

    def _slots(self, g: SectorGeometry) -> np.ndarray:
        return np.rint((g.bearings() - self._ref) / g.angle_increment).astype(np.int64) % self._ring

    def _allocate(self, slots: np.ndarray) -> None:
        budget = self.config.max_map_cells // self._rows   # columns
        new = np.unique(slots[self._col[slots] < 0])
        new = new[:max(0, budget - self.columns)]
        if new.size == 0:
            return
        cap = self._s.shape[1]
        if self.columns + new.size > cap:  # grow geometrically (amortised O(1) a column), within budget
            more = min(max(self.columns + new.size, 2 * cap), budget) - cap
            self._s = np.concatenate([self._s, np.zeros((self._rows, more), np.float32)], axis=1)
            self._w = np.concatenate([self._w, np.zeros(more, np.float32)])
            self._t_last = np.concatenate([self._t_last, np.zeros(more)])
            self._t_first = np.concatenate([self._t_first, np.full(more, np.nan)])
        self._col[new] = self.columns + np.arange(new.size)
        self.columns += new.size

    def update(self, echo: np.ndarray, geometry: SectorGeometry, t: float) -> None:
        """One look at every cell of a sector: ``echo`` (bins x beams, bool) marks cells that echoed."""
        if not self._matches(geometry):
            self._start(geometry)
        slots = self._slots(geometry)
        self._allocate(slots)
        cols = self._col[slots]
        ok = np.flatnonzero(cols >= 0)
        if ok.size == 0:
            return
        k = self.bins_per_cell
        if k > 1:  # a map cell echoed if any of its bins did
            pad = self._rows * k - geometry.n_bins
            echo = np.asarray(np.pad(echo, ((0, pad), (0, 0))).reshape(self._rows, k, -1).any(axis=1))
        c = cols[ok]
        decay = _decay(self._t_last, self._t_first, c, t, self.config.time_constant)
        first = int(c[0])
        if c.size == echo.shape[1] and np.all(np.diff(c) == 1):
            # A frame whose beams are consecutive columns (an imaging sonar): in place, no copies.
            s = self._s[:, first:first + c.size]
            np.multiply(s, decay, out=s)
            np.add(s, echo, out=s)
        else:
            self._s[:, c] = self._s[:, c] * decay + echo[:, ok]
        self._w[c] = self._w[c] * decay + 1.0

    def persistent(self, rows: np.ndarray, beams: np.ndarray, geometry: SectorGeometry, t: float) -> np.ndarray:
        """Whether cells ``(rows, beams)`` of a sector with ``geometry`` lie on (or within ``margin``
        map cells of) persistent map cells."""
        rows, beams = np.asarray(rows, np.intp), np.asarray(beams, np.intp)
        out = np.zeros(rows.shape, bool)
        if not self._matches(geometry) or rows.size == 0:
            return out
        map_rows = rows // self.bins_per_cell
        slots = self._slots(geometry)[beams]
        m = self.config.margin
        for dr in range(-m, m + 1):
            rr = map_rows + dr
            inside = (rr >= 0) & (rr < self._rows)
            for db in range(-m, m + 1):
                cols = np.where(inside, self._col[(slots + db) % self._ring], -1)
                ok = np.flatnonzero(cols >= 0)
                c, r = cols[ok], rr[ok]
                out[ok] |= _persistent(self._s[r, c], self._w[c], t - self._t_first[c], t - self._t_last[c],
                                       self.config)
        return out

    def persistent_mask(self, geometry: SectorGeometry, t: float) -> np.ndarray:
        """Persistent cells of a whole sector (bins x beams, bool), for inspection and plots."""
        rows, beams = np.indices(geometry.shape)
        return self.persistent(rows.ravel(), beams.ravel(), geometry, t).reshape(geometry.shape)


class WarmUp:
    """When the background started learning; echoes are held back while it is younger than
    ``min_echo_time`` (``warmup``), since until then structure cannot be told from a target."""

    def __init__(self) -> None:
        self.start: float | None = None

    def reset(self) -> None:
        self.start = None

    def holding(self, t: float, config: StructureConfig) -> bool:
        """Whether output at time ``t`` is held back."""
        if not (config.enabled and config.warmup and config.persistence_veto):
            return False
        if self.start is None or t < self.start:
            self.start = t
        return t - self.start < config.min_echo_time


class GridBackground:
    """Echo frequency per cell of a square world-frame grid in a window that follows the sonar.

    The window is ``2 reach`` wide around the sonar position (``reach`` = the sector's maximum
    range), on a global lattice of ``cell`` metres so a moved window keeps the history of the cells
    it still covers. Cells are coarsened if the window would exceed ``max_map_cells``.

    Storage wraps around: global cell ``(i, j)`` of an ``n`` x ``n`` window lives in slot
    ``(i mod n, j mod n)``, so a window moved by a few cells clears the rows and columns of slots the
    cells that left it held and copies nothing.
    """

    def __init__(self, config: StructureConfig, cell: float) -> None:
        if not cell > 0:
            raise ValueError(f'world map cell = {cell} m must be > 0')
        self.config = config
        self.requested_cell = float(cell)
        self.reset()

    def reset(self) -> None:
        """Forget everything."""
        self.cell = self.requested_cell
        self._i0 = self._j0 = 0
        self._n = 0
        self._s = np.zeros(0, np.float32)
        self._w = np.zeros(0, np.float32)
        self._t_last = np.zeros(0)
        self._t_first = np.zeros(0)

    def _follow(self, x: float, y: float, reach: float) -> None:
        """Move (and size) the window to cover ``reach`` metres around ``(x, y)``."""
        cell = max(self.requested_cell, 2.0 * reach / math.sqrt(self.config.max_map_cells))
        if cell != self.cell and self._n:
            self.reset()  # the reach grew past what the memory bound allows at this cell size
        self.cell = cell
        n = int(math.ceil(2.0 * reach / cell)) + 2
        i0, j0 = int(math.floor((x - reach) / cell)) - 1, int(math.floor((y - reach) / cell)) - 1
        if (i0, j0, n) == (self._i0, self._j0, self._n):
            return
        if n == self._n:
            # Moved: the slots of the rows and columns that left now hold those that entered.
            self._clear(_entered(self._i0, i0, n), _entered(self._j0, j0, n))
            self._i0, self._j0 = i0, j0
            return
        new: dict[str, np.ndarray] = {'s': np.zeros(n * n, np.float32), 'w': np.zeros(n * n, np.float32),
                                      't_last': np.zeros(n * n), 't_first': np.full(n * n, np.nan)}
        if self._n:
            # Copy the overlap of the old window (global indices i0.., j0..) into the new one.
            a0, a1 = max(i0, self._i0), min(i0 + n, self._i0 + self._n)
            b0, b1 = max(j0, self._j0), min(j0 + n, self._j0 + self._n)
            if a0 < a1 and b0 < b1:
                gi, gj = np.arange(a0, a1), np.arange(b0, b1)
                src = ((gi % self._n)[:, None] * self._n + (gj % self._n)[None, :]).ravel()
                dst = ((gi % n)[:, None] * n + (gj % n)[None, :]).ravel()
                for name in new:
                    new[name][dst] = getattr(self, '_' + name)[src]
        self._s, self._w, self._t_last, self._t_first = new['s'], new['w'], new['t_last'], new['t_first']
        self._i0, self._j0, self._n = i0, j0, n

    def _clear(self, rows: np.ndarray, cols: np.ndarray) -> None:
        """Slot rows ``rows`` and slot columns ``cols`` back to cells never looked at."""
        n = self._n
        for name, value in (('_s', 0.0), ('_w', 0.0), ('_t_last', 0.0), ('_t_first', np.nan)):
            grid = getattr(self, name).reshape(n, n)
            grid[rows, :] = value
            grid[:, cols] = value

    def _index(self, x: np.ndarray, y: np.ndarray, di: int = 0, dj: int = 0) -> np.ndarray:
        """Flat slot of the cell ``(di, dj)`` cells from each world point's, -1 outside the window."""
        i = np.floor(np.asarray(x) / self.cell).astype(np.int64) - self._i0 + di
        j = np.floor(np.asarray(y) / self.cell).astype(np.int64) - self._j0 + dj
        ok = (i >= 0) & (i < self._n) & (j >= 0) & (j < self._n)
        return np.where(ok, ((i + self._i0) % self._n) * self._n + (j + self._j0) % self._n, -1)

    def update(self, samples, sensor_xy: tuple[float, float], reach: float, t: float) -> None:
        """One look: ``samples`` yields ``(x, y, echo)`` arrays of world points seen in this look (any
        number of chunks); every map cell with a point was looked at, and echoed if any point did."""
        self._follow(sensor_xy[0], sensor_xy[1], reach)
        seen = np.zeros(self._n * self._n, bool)
        hit = np.zeros(self._n * self._n, bool)
        for x, y, echo in samples:
            idx = self._index(x, y)
            ok = idx >= 0
            seen[idx[ok]] = True
            hit[idx[ok & np.asarray(echo, bool)]] = True
        self._look(seen, hit, t)

    def update_raster(self, xs: np.ndarray, ys: np.ndarray, seen: np.ndarray, echo: np.ndarray,
                      sensor_xy: tuple[float, float], reach: float, t: float) -> None:
        """One look at an axis-aligned raster: pixel ``[j, i]`` is at ``(xs[i], ys[j])``; ``seen`` and
        ``echo`` (bool, ``(len(ys), len(xs))``) mark the pixels looked at and those that echoed."""
        self._follow(sensor_xy[0], sensor_xy[1], reach)
        i = np.floor(np.asarray(xs) / self.cell).astype(np.int64) - self._i0
        j = np.floor(np.asarray(ys) / self.cell).astype(np.int64) - self._j0
        ci, cj = (i >= 0) & (i < self._n), (j >= 0) & (j < self._n)
        idx = ((i[None, ci] + self._i0) % self._n) * self._n + (j[cj, None] + self._j0) % self._n
        sub = np.ix_(cj, ci)
        seen_map = np.zeros(self._n * self._n, bool)
        hit = np.zeros(self._n * self._n, bool)
        seen_map[idx[seen[sub]]] = True
        hit[idx[echo[sub] & seen[sub]]] = True
        self._look(seen_map, hit, t)

    def update_sector(self, echo: np.ndarray, geometry: SectorGeometry, pose: tuple[float, float, float],
                      reach: float, t: float) -> None:
        """One look at a whole sector taken at ``pose``: what :meth:`update` does with the world
        positions of all its cells (:func:`_sector_points`), computed cell by cell in one compiled
        pass instead of arrays over the sector."""
        self._follow(pose[0], pose[1], reach)
        seen = np.zeros(self._n * self._n, np.bool_)
        hit = np.zeros(self._n * self._n, np.bool_)
        r, cos_b, sin_b = _sector_axes(geometry, pose)
        _place_sector(r, cos_b, sin_b, float(pose[0]), float(pose[1]), self.cell, self._i0, self._j0, self._n,
                      self._i0 % self._n, self._j0 % self._n, np.ascontiguousarray(echo, np.bool_), seen, hit)
        forget = _FORGET * self.config.time_constant
        keys = np.empty(_LAST_LOOKS)
        table = np.full(2 * _LAST_LOOKS, -1, np.int64)
        bits = self._t_last.view(np.int64)
        n = _last_looks(seen, self._t_last, bits, self._t_first, float(t), forget, keys, table)
        if n < 0:   # more distinct previous looks than the compiled pass takes
            self._look(seen, hit, t)
            return
        # exp by numpy, as _decay takes it, once per previous look time (the cells share few)
        decays = np.exp(-np.maximum(t - keys[:n], 0.0) / self.config.time_constant).astype(np.float32)
        _apply_look(seen, hit, self._s, self._w, self._t_last, bits, self._t_first, float(t), forget,
                    keys.view(np.int64), table, decays)

    def _look(self, seen: np.ndarray, hit: np.ndarray, t: float) -> None:
        """The echo-frequency rule on the cells ``seen`` (flat bool), echo where ``hit``."""
        c = np.flatnonzero(seen)
        if c.size == 0:
            return
        decay = _decay(self._t_last, self._t_first, c, t, self.config.time_constant)
        self._s[c] = self._s[c] * decay + hit[c]
        self._w[c] = self._w[c] * decay + 1.0

    def persistent(self, x: np.ndarray, y: np.ndarray, t: float) -> np.ndarray:
        """Whether world points lie on persistent map cells."""
        x = np.asarray(x, float)
        out = np.zeros(x.shape, bool)
        if self._n == 0 or x.size == 0:
            return out
        m = self.config.margin
        for di in range(-m, m + 1):
            for dj in range(-m, m + 1):
                idx = self._index(x, y, di, dj)
                ok = np.flatnonzero(idx >= 0)
                c = idx[ok]
                out[ok] |= _persistent(self._s[c], self._w[c], t - self._t_first[c], t - self._t_last[c],
                                       self.config)
        return out


def _sector_points(geometry: SectorGeometry, pose: tuple[float, float, float], rows: np.ndarray,
                   beams: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World positions of sector cells ``(rows, beams)`` seen from ``pose``."""
    r = geometry.range_min + geometry.range_resolution * np.asarray(rows, float)
    b = geometry.angle_min + geometry.angle_increment * np.asarray(beams, float) + pose[2]
    return pose[0] + r * np.cos(b), pose[1] + r * np.sin(b)


def _sector_axes(geometry: SectorGeometry, pose: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray,
                                                                                      np.ndarray]:
    """Range of every row and the cosine and sine of every beam's world bearing, each value as
    :func:`_sector_points` computes it for a cell of that row or beam."""
    r = geometry.range_min + geometry.range_resolution * np.arange(geometry.n_bins, dtype=float)
    b = geometry.angle_min + geometry.angle_increment * np.arange(geometry.n_beams, dtype=float) + pose[2]
    return r, np.cos(b), np.sin(b)


def _entered(old: int, new: int, n: int) -> np.ndarray:
    """Slots (mod ``n``) of the global rows (or columns) in ``new .. new + n - 1`` that were not in
    ``old .. old + n - 1``: all ``n`` when the window moved by ``n`` or more."""
    if abs(new - old) >= n:
        return np.arange(n)
    first = old + n if new > old else new
    return np.arange(first, first + abs(new - old)) % n


@kernel
def _place_sector(r, cos_b, sin_b, x0, y0, cell, i0, j0, n, slot_i0, slot_j0, echo, seen, hit):
    """Marks the slots of the window's cells (``n`` x ``n`` from global cell ``(i0, j0)``, whose
    slot is ``(slot_i0, slot_j0)``) that hold a sector cell's world position
    ``(x0 + r cos b, y0 + r sin b)`` as seen, and as hit where it echoed."""
    for row in range(r.shape[0]):
        rr = r[row]
        for beam in range(cos_b.shape[0]):
            i = np.int64(np.floor((x0 + rr * cos_b[beam]) / cell)) - i0
            j = np.int64(np.floor((y0 + rr * sin_b[beam]) / cell)) - j0
            if 0 <= i < n and 0 <= j < n:
                i += slot_i0
                j += slot_j0
                k = (i - n if i >= n else i) * n + (j - n if j >= n else j)
                seen[k] = True
                if echo[row, beam]:
                    hit[k] = True


@kernel
def _slot_of(key, keys, table):
    """The hash-table slot of the float64 bit pattern ``key`` (open addressing over ``table``, which
    holds indices into ``keys``, -1 where empty): where it is, or the empty slot it would take."""
    mask = table.shape[0] - 1
    h = np.int64((np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(40)) & mask
    while table[h] >= 0 and keys[table[h]] != key:
        h = (h + 1) & mask
    return h


@kernel
def _last_looks(seen, t_last, bits, t_first, t, forget, keys, table):
    """The distinct previous look times of the cells ``seen`` that keep their history (not fresh, see
    :func:`_decay`), into ``keys``, indexed by their bit patterns (``bits``: ``t_last`` as int64) in
    ``table``; returns how many, or -1 when they do not fit."""
    key_bits = keys.view(np.int64)
    n = 0
    last = np.int64(0)
    have_last = False
    for k in range(seen.shape[0]):
        if not seen[k] or np.isnan(t_first[k]) or max(t - t_last[k], 0.0) > forget:
            continue
        b = bits[k]
        if have_last and b == last:
            continue
        h = _slot_of(b, key_bits[:n], table)
        if table[h] < 0:
            if n == keys.shape[0]:
                return -1
            keys[n] = t_last[k]
            table[h] = n
            n += 1
        last = b
        have_last = True
    return n


@kernel
def _apply_look(seen, hit, s, w, t_last, bits, t_first, t, forget, key_bits, table, decays):
    """The echo-frequency rule (:func:`_decay`, then ``S <- S d + z``, ``W <- W d + 1`` in float32) on
    the cells ``seen``; a cell that keeps its history takes the factor ``decays[m]`` of its previous
    look time, entry ``m`` of :func:`_last_looks`' table."""
    zero = np.float32(0.0)
    one = np.float32(1.0)
    n = decays.shape[0]
    last = np.int64(0)
    d_last = zero
    have_last = False
    for k in range(seen.shape[0]):
        if not seen[k]:
            continue
        if np.isnan(t_first[k]) or max(t - t_last[k], 0.0) > forget:
            d = zero
            t_first[k] = t
        else:
            b = bits[k]
            if not (have_last and b == last):
                d_last = decays[table[_slot_of(b, key_bits[:n], table)]]
                last = b
                have_last = True
            d = d_last
        t_last[k] = t
        s[k] = s[k] * d + (one if hit[k] else zero)
        w[k] = w[k] * d + one


class SectorBackground:
    """The persistent-echo background of a sector sonar: the sensor-frame polar map, and the
    world-frame grid once the sonar moves (``map`` setting, see module docstring)."""

    def __init__(self, config: StructureConfig) -> None:
        self.config = config
        self.polar = PolarBackground(config)
        self.grid: GridBackground | None = None
        self.reset()

    def reset(self) -> None:
        """Forget everything, including where the sonar was."""
        self.polar.reset()
        self.grid = None
        self._first_pose: tuple[float, float, float] | None = None
        self.moving = False

    def _maps(self, geometry: SectorGeometry, pose: tuple[float, float, float]) -> tuple[bool, bool]:
        """Which maps are in use: (sensor, world)."""
        mode = self.config.map
        if mode != 'auto':
            return mode == 'sensor', mode == 'world'
        if not self.moving:
            if self._first_pose is None:
                self._first_pose = (float(pose[0]), float(pose[1]), float(pose[2]))
            p0 = self._first_pose
            moved = math.hypot(pose[0] - p0[0], pose[1] - p0[1]) > 0.5 * max(geometry.range_resolution, 1e-9)
            turned = abs(math.remainder(pose[2] - p0[2], 2 * math.pi)) > 0.5 * geometry.angle_increment
            self.moving = moved or turned
        return True, self.moving

    def _grid(self, geometry: SectorGeometry) -> GridBackground:
        if self.grid is None:
            g = geometry
            mid = 0.5 * (g.range_min + g.range_max)
            cell = self.config.world_cell or max(g.range_resolution, mid * g.angle_increment, 1e-3)
            self.grid = GridBackground(self.config, cell)
        return self.grid

    def update(self, echo: np.ndarray, geometry: SectorGeometry, pose: tuple[float, float, float], t: float) -> None:
        """One look at a sector taken at ``pose`` (world frame); ``echo`` marks cells that echoed."""
        sensor, world = self._maps(geometry, pose)
        if sensor:
            self.polar.update(echo, geometry, t)
        if not world:
            return
        reach = geometry.range_max + geometry.range_resolution
        self._grid(geometry).update_sector(echo, geometry, pose, reach, t)

    def persistent(self, rows: np.ndarray, beams: np.ndarray, geometry: SectorGeometry,
                   pose: tuple[float, float, float], t: float) -> np.ndarray:
        """Whether sector cells ``(rows, beams)`` lie on persistent cells of either map (decided
        before this look's :meth:`update`)."""
        sensor, world = self._maps(geometry, pose)
        out = self.polar.persistent(rows, beams, geometry, t) if sensor else np.zeros(np.shape(rows), bool)
        if world and self.grid is not None:
            x, y = _sector_points(geometry, pose, rows, beams)
            out |= self.grid.persistent(x, y, t)
        return out
