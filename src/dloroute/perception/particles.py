"""Ordered rope particles from a centre-line: a compass walk with the rope's particle spacing.

The simulated rope is a chain of straight edges of fixed length (RopeSpec.spacing), so particle k + 1 is
the first point along the centre-line, after particle k, at exactly one spacing from it. Particles
beyond the measured centre-line (the tail out of the image) continue straight along the last measured
direction, one spacing apart.
"""

from __future__ import annotations

import numpy as np


def _exit_point(a: np.ndarray, b: np.ndarray, centre: np.ndarray, radius: float, t_min: float) -> float | None:
    """Smallest t in [t_min, 1] where a + t (b - a) leaves the circle (centre, radius), else None."""
    ab, ac = b - a, a - centre
    qa, qb, qc = ab @ ab, 2.0 * (ab @ ac), ac @ ac - radius * radius
    if qa < 1e-18:
        return None
    disc = qb * qb - 4.0 * qa * qc
    if disc < 0:
        return None
    t = (-qb + np.sqrt(disc)) / (2.0 * qa)  # the larger root: where the segment leaves the circle
    return float(t) if t_min - 1e-12 <= t <= 1.0 else None


def compass_walk(line: np.ndarray, n: int, spacing: float) -> tuple[np.ndarray, int]:
    """``n`` points (n, 2) one ``spacing`` apart along ``line`` (k, 2), from line[0]; units as given.

    Returns the points and how many were found on the line; the others are extrapolated straight.
    """
    line = np.asarray(line, dtype=float)
    out = [line[0]]
    seg, t = 0, 0.0
    while len(out) < n and seg < len(line) - 1:
        hit = _exit_point(line[seg], line[seg + 1], out[-1], spacing, t)
        if hit is None:
            seg, t = seg + 1, 0.0
            continue
        t = hit
        out.append(line[seg] + t * (line[seg + 1] - line[seg]))
    found = len(out)
    if found < n:
        if found >= 2:
            d = out[-1] - out[-2]
        else:
            d = line[-1] - line[0] if len(line) > 1 else np.array([1.0, 0.0])
        d = d / max(np.linalg.norm(d), 1e-12)
        last = out[-1]
        out.extend(last + spacing * (i + 1) * d for i in range(n - found))
    return np.array(out[:n]), min(found, n)
