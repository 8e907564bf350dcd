"""A top view of the cage (x right, z up the image) as an RGB array."""

from __future__ import annotations

import numpy as np

#: Fish colours per behaviour index (cycled).
COLOURS = np.array(
    [[240, 128, 48], [250, 220, 70], [230, 70, 90], [120, 200, 120], [190, 140, 240]],
    dtype=np.uint8,
)
WATER = np.array([14, 42, 70], dtype=np.uint8)
NET = np.array([200, 210, 220], dtype=np.uint8)


def top_view(core, behaviours, size: int = 512) -> np.ndarray:
    """Cage outline, obstacles and every fish (a dot of its body length with a
    line along its heading, coloured by behaviour), seen from above."""
    if size < 16:
        raise ValueError(f"render size must be at least 16 pixels, got {size}")
    outline = np.asarray(core.cage_outline(), dtype=np.float64)
    half = np.abs(outline).max() * 1.08
    scale = (size - 1) / (2 * half)

    def to_px(x, z):
        return (x + half) * scale, (half - z) * scale

    image = np.empty((size, size, 3), dtype=np.uint8)
    image[:] = WATER
    for (x0, z0), (x1, z1) in zip(outline[:-1], outline[1:]):
        _line(image, *to_px(x0, z0), *to_px(x1, z1), NET)
    ys, xs = np.mgrid[0:size, 0:size]
    for x, z, r in core.obstacle_discs():
        px, py = to_px(x, z)
        image[(xs - px) ** 2 + (ys - py) ** 2 <= (r * scale) ** 2] = NET // 2
    state = core.state()
    px, py = to_px(state[:, 0].astype(np.float64), state[:, 2].astype(np.float64))
    bl = state[:, 7] * scale
    colour = COLOURS[state[:, 8].astype(np.int64) % len(COLOURS)]
    # Heading lines first, bodies on top.
    for k in np.linspace(0.0, 0.8, 16):
        hx = np.rint(px + state[:, 3] * bl * k).astype(np.int64)
        hy = np.rint(py - state[:, 5] * bl * k).astype(np.int64)
        _put(image, hx, hy, colour)
    radius = np.clip(bl * 0.12, 1.5, 3.0)
    for dx in range(-3, 4):
        for dy in range(-3, 4):
            near = dx * dx + dy * dy <= radius * radius
            _put(image, np.rint(px + dx)[near].astype(np.int64),
                 np.rint(py + dy)[near].astype(np.int64), colour[near])
    return image


def _put(image, x, y, colour):
    ok = (x >= 0) & (y >= 0) & (x < image.shape[1]) & (y < image.shape[0])
    image[y[ok], x[ok]] = colour[ok] if colour.ndim == 2 else colour


def _line(image, x0, y0, x1, y1, colour):
    n = int(max(abs(x1 - x0), abs(y1 - y0))) + 1
    t = np.linspace(0.0, 1.0, n + 1)
    x = np.rint(x0 + (x1 - x0) * t).astype(np.int64)
    y = np.rint(y0 + (y1 - y0) * t).astype(np.int64)
    _put(image, x, y, colour)
