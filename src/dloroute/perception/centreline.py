"""The rope's centre-line in one image: traced from its mask, bridged under clips, ordered end to end.

Tracing works in continuous pixel coordinates (u right, v down; pixel (row i, column j) covers
[j, j + 1) x [i, i + 1)). From a seed on a straight stretch it walks both ways in steps of ``step`` px:
predict ahead along the current direction, then re-centre on the rope across the direction (a cross
section of the mask). A cross section much wider than the rope (the rope crossing itself) keeps the
prediction, so the walk goes straight through crossings. Where the rope runs into a clip's silhouette it
is hidden under the roof: the walk bridges the clip with a straight segment (the tunnel is 2 cm long) to
where the rope comes out on the far side. A walk ends at the image border ("border"), at a free end in the
open ("free") or at a clip ("occluded": the rope goes under the roof and nothing comes out, the end is
inside the tunnel or pressed against its face, and is put where it disappears, so it may lie up to a
roof's depth further in; or the rope ends against the clip's side).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

EndKind = Literal["free", "border", "occluded"]

WIDE = 1.6
"""A cross section wider than this many rope widths is a crossing or a blob: not used to re-centre."""
NARROW = 0.6
"""An uncut cross section narrower than this many rope widths is the rope's rounded end: no rope there."""
EXIT_ANGLE = math.radians(60)
"""Under a clip, the rope comes out at most this far (rad) from the direction it went in."""
OPPOSITE = math.cos(math.radians(120))
"""Two arms of a crossing at least 120 deg apart are one strand passing through it."""
GRAZE = 2.0
"""A rope passing a clip's corner or side (not through it) may hide under the roof's edge for this many
rope widths."""
BORDER_MARGIN = 1.5
"""Distance (px) from the image border where a walk counts as leaving the image."""


@dataclass(frozen=True, eq=False)
class Occluder:
    """A clip in the image: its silhouette (rows, cols) bool, and its tunnel in pixel coordinates.

    ``centre`` (px) is the clip's origin, ``axis`` the unit vector of its +x (insertion) axis, and
    ``half_opening`` (px) how far from the axis a rope through the tunnel can lie (half the opening plus
    the rope's radius and a margin).
    """

    mask: np.ndarray
    centre: np.ndarray
    axis: np.ndarray
    half_opening: float

    @property
    def span(self) -> float:
        """Diagonal (px) of the silhouette's bounding box: the longest bridge under it."""
        rows, cols = np.nonzero(self.mask)
        return float(np.hypot(np.ptp(rows) + 1, np.ptp(cols) + 1)) if rows.size else 0.0

    def local(self, p: np.ndarray) -> np.ndarray:
        """Point(s) (..., 2) px -> (along the axis, across it) px from the centre."""
        rel = np.asarray(p) - self.centre
        return np.stack([rel @ self.axis, rel @ np.array([-self.axis[1], self.axis[0]])], axis=-1)

    def faces(self, p: np.ndarray, d: np.ndarray) -> bool:
        """True when a rope at ``p`` heading ``d`` runs into the entry or exit face (can go through)."""
        return bool(abs(self.local(p)[1]) <= self.half_opening and abs(d @ self.axis) >= math.cos(EXIT_ANGLE)
                    and (self.centre - p) @ d > 0)


@dataclass(frozen=True, eq=False)
class Centreline:
    """An ordered centre-line (k, 2) in pixels from one end (``start``) to the other (``stop``).

    ``visible[i]`` is False where point i was bridged under a clip rather than measured.
    """

    points: np.ndarray
    visible: np.ndarray
    start: EndKind
    stop: EndKind

    def reversed(self) -> Centreline:
        return Centreline(self.points[::-1].copy(), self.visible[::-1].copy(), self.stop, self.start)


def sample(image: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Bilinear samples of ``image`` (rows, cols[, channels]) at continuous pixel points (..., 2).

    Bool masks sample as 0/1; points outside the image read 0. Returns (...[, channels]).
    """
    rows, cols = image.shape[:2]
    pts = np.asarray(pts, dtype=float)
    shape = pts.shape[:-1] + image.shape[2:]
    x = pts.reshape(-1, 2)[:, 0] - 0.5
    y = pts.reshape(-1, 2)[:, 1] - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    out = np.zeros((x.size, *image.shape[2:]))
    for dx, dy, w in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)), (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
        xi, yi = x0 + dx, y0 + dy
        ok = (xi >= 0) & (xi < cols) & (yi >= 0) & (yi < rows)
        out[ok] += w[ok].reshape(-1, *[1] * (image.ndim - 2)) * image[yi[ok], xi[ok]]
    return out.reshape(shape)


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-9 else v


def cross_section(layers: np.ndarray, q: np.ndarray, d: np.ndarray, width: float,
                  reach: float | None = None) -> tuple[float, bool] | None:
    """Lateral offset (px) of the rope's centre across direction ``d`` at point ``q`` and whether the
    section is a crossing; None where there is no rope.

    ``layers`` (rows, cols, 2) holds the rope mask and the clips' silhouettes (``hidden``) as floats.
    Takes the run of rope pixels nearest ``q``, up to ``reach`` px aside (default 0.75 rope widths). A
    run cut by a clip on one side is centred from its other edge, one cut on both sides keeps offset 0;
    a run wider than WIDE rope widths is a crossing (offset 0: go straight on); an uncut run narrower
    than NARROW rope widths is no rope.
    """
    reach = 0.75 * width if reach is None else reach
    half = reach + WIDE * width + 1.0
    t = np.arange(-half, half + 1e-9, 0.25)
    normal = np.array([-d[1], d[0]])
    values = sample(layers, q[None, :] + t[:, None] * normal[None, :]) >= 0.5
    inside, occluded = values[:, 0], values[:, 1]
    if not inside.any():
        return None
    idx = np.flatnonzero(inside)
    k = int(idx[np.argmin(np.abs(t[idx]))])
    if abs(t[k]) > reach:
        return None
    lo, hi = k, k
    while lo > 0 and inside[lo - 1]:
        lo -= 1
    while hi < len(t) - 1 and inside[hi + 1]:
        hi += 1
    cut_lo = lo == 0 or occluded[max(lo - 2, 0): lo].any()
    cut_hi = hi == len(t) - 1 or occluded[hi + 1: hi + 3].any()
    a, b = t[lo] - 0.125, t[hi] + 0.125
    if b - a < NARROW * width and not (cut_lo or cut_hi):
        return None
    if b - a > WIDE * width:
        return 0.0, True
    if cut_lo and cut_hi:
        return 0.0, False
    if cut_lo:
        return b - width / 2, False
    if cut_hi:
        return a + width / 2, False
    return (a + b) / 2, False


class Tracer:
    """Walks a rope mask. ``width`` is the rope's diameter (px), ``step`` the walking step (px)."""

    def __init__(self, mask: np.ndarray, occluders: Sequence[Occluder], width: float, step: float = 1.5):
        self.mask = mask
        self.occluders = list(occluders)
        self.hidden = np.zeros_like(mask, dtype=bool)
        for o in self.occluders:
            self.hidden |= o.mask
        self._patches: dict[int, list[np.ndarray]] = {}
        self.layers = np.stack([mask, self.hidden], axis=-1).astype(np.float32)
        self.width = width
        self.step = step
        rows, cols = mask.shape
        self._size = np.array([cols, rows], dtype=float)

    def _outside(self, q: np.ndarray, margin: float = BORDER_MARGIN) -> bool:
        """True when ``q`` (px) lies within ``margin`` of the image border, or beyond it."""
        return bool((q < margin).any() or (q > self._size - margin).any())

    def _occluder_near(self, p: np.ndarray, d: np.ndarray) -> Occluder | None:
        """The clip whose silhouette lies just ahead of ``p`` (within a rope width), if any."""
        probes = p[None, :] + np.linspace(0.0, self.step + self.width, 8)[:, None] * d[None, :]
        for o in self.occluders:
            if (sample(o.mask, probes) >= 0.5).any():
                return o
        return None

    def seed(self) -> tuple[np.ndarray, np.ndarray] | None:
        """A point on a straight, uncrowded stretch of rope and the rope's direction there."""
        m = self.mask.astype(np.uint8)
        if m.sum() < 3:
            return None
        k = max(3, int(round(4 * self.width)) | 1)  # a window holding 4 rope widths of straight rope
        count = cv2.boxFilter(m.astype(np.float32), -1, (k, k), normalize=False)
        dist = cv2.distanceTransform(m, cv2.DIST_L2, 3)
        centre = (dist >= max(1.0, 0.5 * self.width - 0.75)) & ~cv2.dilate(self.hidden.astype(np.uint8),
                                                                             np.ones((k, k), np.uint8)).astype(bool)
        if not centre.any():
            centre = m.astype(bool)
        score = np.where(centre, np.abs(count - k * self.width), np.inf)
        score[:k], score[-k:], score[:, :k], score[:, -k:] = np.inf, np.inf, np.inf, np.inf  # not at the border
        if not np.isfinite(score).any():
            return None
        r, c = np.unravel_index(int(np.argmin(score)), score.shape)
        p = np.array([c + 0.5, r + 0.5])
        rr, cc = np.nonzero(m[max(r - k, 0): r + k + 1, max(c - k, 0): c + k + 1])
        pts = np.stack([cc, rr], axis=-1).astype(float)
        _, evecs = np.linalg.eigh(np.cov((pts - pts.mean(axis=0)).T))
        return p, evecs[:, 1]

    def walk(self, p: np.ndarray, d: np.ndarray, max_steps: int) -> tuple[list[np.ndarray], list[bool], EndKind]:
        """Points after ``p`` going along ``d``, their visibility, and how the walk ended.

        A walk that uses up ``max_steps`` (a rope longer than it can be) counts as leaving the image.
        """
        pts: list[np.ndarray] = [p]
        vis: list[bool] = [True]
        crossing_from: int | None = None  # index of the last point before the crossing being walked
        for _ in range(max_steps):
            q = pts[-1] + self.step * d
            if self._outside(q):
                return pts, vis, "border"
            section = cross_section(self.layers, q, d, self.width)
            if section is None and crossing_from is None:  # a crack in the mask: look one step further
                jump = cross_section(self.layers, q + self.step * d, d, self.width)
                if jump is not None and not jump[1] and abs(jump[0]) < 0.5 * self.width:
                    q, section = q + self.step * d, jump
            if section is not None:
                offset, wide = section
                if not wide:
                    crossing_from = None
                elif crossing_from is None:
                    crossing_from = len(pts) - 1
                q = q + offset * np.array([-d[1], d[0]])
                if len(pts) >= 3:  # the direction from a few steps back: less noisy than the last step
                    d = _unit(q - pts[max(0, len(pts) - 4)])
                pts.append(q)
                vis.append(True)
                continue
            if crossing_from is not None:  # lost in a crossing: find the arm that continues the rope
                q, onward = self._beyond_crossing(pts[crossing_from], pts[-1], d)
                pts, vis = pts[: crossing_from + 1], vis[: crossing_from + 1]
                if onward is None:  # the rope ends at the strand it crossed
                    pts.append(q)
                    vis.append(True)
                    return pts, vis, "free"
                crossing_from, d = None, onward
                n = max(1, int(np.ceil(np.linalg.norm(q - pts[-1]) / self.step)))
                pts.extend(pts[-1] + (q - pts[-1]) * (i / n) for i in range(1, n + 1))
                vis.extend([True] * n)
                continue
            occ = self._occluder_near(pts[-1], d)
            through = occ is not None and occ.faces(pts[-1], d)
            bridged = self._bridge(pts[-1], d, occ) if through else self._graze(pts[-1], d, occ)
            if bridged is None:
                if through:  # the end is hidden under the roof: keep where it disappears
                    pts.append(pts[-1] + self._chord(pts[-1], d, occ)[0] * d)
                else:  # an end in the open, or against a clip's side
                    pts.append(self._free_end(pts[-1], d))
                vis.append(True)
                if self._outside(pts[-1], margin=BORDER_MARGIN + self.width):
                    return pts, vis, "border"  # lost at the border: the rope may go on outside
                return pts, vis, "free" if occ is None else "occluded"
            path, d = bridged
            pts.extend(path)
            vis.extend([False] * (len(path) - 1) + [True])
        return pts, vis, "border"

    def _beyond_crossing(self, p: np.ndarray, last: np.ndarray, d: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray | None]:
        """Past a crossing walked from ``p`` to ``last`` heading ``d``: the rope's centre and direction
        where it continues, or its end and None.

        The rope's arms are read on a circle around the crossing. Besides the arm the walk came in by,
        the two most nearly opposite arms (if within OPPOSITE) are the strand crossed; of the remaining
        arms, the one most nearly straight on continues the rope.
        Without one, the end abuts the crossed strand (a T) or pokes out of it: the end is the rope's tip
        along ``d`` when that lies more than a radius beyond the strand, else a radius past its near edge.
        """
        centre = 0.5 * (p + last)
        radius = max(2.5 * self.width, 0.5 * float(np.linalg.norm(last - p)) + 1.5 * self.width)
        angles = np.radians(np.arange(0.0, 360.0, 2.0))
        ring = sample(self.mask, centre + radius * np.stack([np.cos(angles), np.sin(angles)], axis=-1)) >= 0.5
        arms: list[float] = []
        if ring.any() and not ring.all():
            start = int(np.argmin(ring))  # walk the circle from a gap so that no arm wraps around
            run: list[float] = []
            for k in range(start, start + len(ring) + 1):
                if ring[k % len(ring)]:
                    run.append(angles[k % len(ring)] + (2 * np.pi if k >= len(ring) else 0.0))
                elif run:
                    arms.append(float(np.mean(run)))
                    run = []
        heading = [np.array([math.cos(t), math.sin(t)]) for t in arms]
        if heading:  # drop the arm the walk came in by
            heading.pop(int(np.argmin([h @ d for h in heading])))
        others, crossed = heading, None
        if len(others) >= 2:
            pairs = [(i, j) for i in range(len(others)) for j in range(i + 1, len(others))]
            i, j = min(pairs, key=lambda ij: float(others[ij[0]] @ others[ij[1]]))
            if others[i] @ others[j] < OPPOSITE:
                crossed = others[i] - others[j]
                others = [h for k, h in enumerate(others) if k not in (i, j)]
        if others:
            a = max(others, key=lambda h: float(h @ d))
            q = centre + radius * a
            section = None if self._outside(q) else cross_section(self.layers, q, a, self.width)
            if section is not None and not section[1]:
                return q + section[0] * np.array([-a[1], a[0]]), a
        thickness = self.width
        if crossed is not None:
            u = _unit(crossed)
            sin = abs(float(u[0] * d[1] - u[1] * d[0]))
            thickness = self.width / max(sin, 0.3)
        tip = self._free_end(last, d)
        if float((tip - p) @ d) > thickness + 0.5 * self.width:
            return tip, None
        return p + 0.5 * self.width * d, None

    def _free_end(self, p: np.ndarray, d: np.ndarray) -> np.ndarray:
        """The rope's end beyond ``p`` along ``d``: the last point where the mask is set."""
        t = np.arange(0.0, self.step + self.width, 0.25)
        inside = sample(self.mask, p[None, :] + t[:, None] * d[None, :]) >= 0.5
        last = int(np.argmin(inside)) - 1 if not inside.all() else len(t) - 1
        return p + (t[max(last, 0)] + 0.125) * d

    def _contacts(self, occ: Occluder) -> list[np.ndarray]:
        """Patches of rope pixels touching ``occ``'s silhouette (pixel centres, (k, 2) each)."""
        key = id(occ)
        if key not in self._patches:
            near = cv2.dilate(occ.mask.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5)))
            ring = (near.astype(bool) & ~occ.mask & self.mask).astype(np.uint8)
            n, labels = cv2.connectedComponents(ring, connectivity=8)
            self._patches[key] = [np.argwhere(labels == i)[:, ::-1] + 0.5 for i in range(1, n)]
        return self._patches[key]

    def _chord(self, p: np.ndarray, d: np.ndarray, occ: Occluder) -> tuple[float, float]:
        """Distances (px) from ``p`` along ``d`` where the line enters and leaves the silhouettes."""
        s = 0.0
        while s < self.step + self.width and sample(self.hidden, p + s * d) < 0.5:
            s += 0.5
        s_in = s
        while s < s_in + occ.span and sample(self.hidden, p + s * d) >= 0.5:
            s += 0.5
        return s_in, s

    def _bridge(self, p: np.ndarray, d: np.ndarray, occ: Occluder) -> tuple[list[np.ndarray], np.ndarray] | None:
        """Path under ``occ`` from ``p`` to where the rope comes out, and the direction there; None if
        it does not come out.

        Exits are patches of rope touching the silhouette, each at its pixel nearest the clip's centre.
        In order: the patch at the opposite face that lies most nearly
        straight ahead (within EXIT_ANGLE); the rope found straight ahead beyond the silhouette; another
        patch at the same face (the rope turned back under the roof: the path goes to the tunnel's
        middle and back).
        """
        side = np.sign(occ.local(p)[0])
        opposite, same = [], []
        for patch in self._contacts(occ):
            c = patch[np.argmin(np.linalg.norm(patch - occ.centre, axis=1))]  # where it comes out from under
            x, y = occ.local(c)
            if abs(y) > occ.half_opening:
                continue  # beside the clip, not at a face
            if np.sign(x) != side:
                v = c - p
                cos = float(v @ d) / max(float(np.linalg.norm(v)), 1e-9)
                if cos > math.cos(EXIT_ANGLE):
                    opposite.append((cos, c))
            elif np.min(np.linalg.norm(patch - p, axis=1)) > self.width + self.step:
                same.append(c)  # not the patch where the rope goes in
        if opposite:
            target = max(opposite, key=lambda t: t[0])[1]
            return self._straight(p, target, _unit(target - p), 0.0, tip=target)
        ahead = self._straight(p, p, d, self._chord(p, d, occ)[1], tip=None)
        if ahead is not None or not same:
            return ahead
        target = min(same, key=lambda c: float(np.linalg.norm(c - p)))
        across = np.array([-occ.axis[1], occ.axis[0]])
        apex = occ.centre + across * occ.local(0.5 * (p + target))[1]  # on the tunnel's middle line
        n = max(1, int(np.ceil(np.linalg.norm(apex - p) / self.step)))
        inward = [p + (apex - p) * (i / n) for i in range(1, n + 1)]
        back = self._straight(apex, target, _unit(target - apex), 0.0, tip=target)
        return inward + back[0], back[1]

    def _graze(self, p: np.ndarray, d: np.ndarray, occ: Occluder | None) -> tuple[list[np.ndarray], np.ndarray] | None:
        """Path past a clip's corner or side that hides the rope for at most GRAZE rope widths."""
        if occ is None:
            return None
        s_in, s_out = self._chord(p, d, occ)
        if s_out - s_in > GRAZE * self.width:
            return None
        return self._straight(p, p, d, s_out, tip=None)

    def _straight(self, p: np.ndarray, origin: np.ndarray, a: np.ndarray, s: float, tip: np.ndarray | None
                  ) -> tuple[list[np.ndarray], np.ndarray] | None:
        """Straight path from ``p`` to the rope's centre found across ``a`` just beyond ``origin + s a``.

        Without a full cross section there, the path ends at ``tip`` (the rope's visible tip), or None.
        """
        end = tip
        for extra in np.arange(0.0, 2.0 * self.width, 0.5):
            q = origin + (s + extra) * a
            if self._outside(q):
                break
            section = cross_section(self.layers, q, a, self.width, reach=1.5 * self.width)
            if section is not None:
                end = q + section[0] * np.array([-a[1], a[0]])
                break
        if end is None:
            return None
        n = max(1, int(np.ceil(np.linalg.norm(end - p) / self.step)))
        return [p + (end - p) * (i / n) for i in range(1, n + 1)], _unit(end - p)

    def trace(self, max_length: float) -> Centreline | None:
        """The whole visible rope from the seed's stretch, walked both ways; None without a rope."""
        start = self.seed()
        if start is None:
            return None
        p, d = start
        section = cross_section(self.layers, p, d, self.width)
        if section is not None:  # start on the centre line
            p = p + section[0] * np.array([-d[1], d[0]])
        steps = int(max_length / self.step) + 1
        fwd, fvis, fend = self.walk(p, d, steps)
        bwd, bvis, bend = self.walk(p, -d, steps)
        points = np.array(bwd[::-1] + fwd[1:])
        visible = np.array(bvis[::-1] + fvis[1:])
        return Centreline(points, visible, bend, fend)
