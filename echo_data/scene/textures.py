"""Procedural surface textures (numpy only): wood, tiles, carpet, plaster, fabric, concrete,
brick, plus the printed faces of objects (phone screen, clock face, fur, book cover, label).

Why procedural: no asset download, and an image is a pure function of (pattern, variant), so
every worker and every replay renders the same pixels. Each texture is a small greyscale
*detail* map (mean about 1) that the caller multiplies by the surface colour; colour therefore
stays the surface's (and the room's) while the pattern is the material's. Results are cached
per process: a handful of variants per pattern, built once and reused by every episode.
"""

from __future__ import annotations

import zlib
from functools import cache, lru_cache
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # sapien is imported where a material is made
    import sapien

SIZE = 128  # texels per side; the textures repeat (tile) in world space
VARIANTS = 4  # variants per pattern; a surface picks one from its plan seed
PATTERNS = (
    "wood", "tiles", "carpet", "plaster", "fabric", "concrete", "brick",
    "screen", "clock_face", "fur", "cover", "label", "plain",
)


def _rng(pattern: str, variant: int) -> np.random.Generator:
    return np.random.default_rng([zlib.crc32(pattern.encode()), variant])


def _smooth_noise(rng: np.random.Generator, n: int, cells: int) -> np.ndarray:
    """Tileable value noise in [0, 1]: a random `cells`² grid, bilinearly upsampled with wrap."""
    g = rng.random((cells, cells))
    t = np.arange(n) * cells / n
    i0 = np.floor(t).astype(int)
    f = t - i0
    f = f * f * (3 - 2 * f)
    i1 = (i0 + 1) % cells
    a = g[i0][:, i0] * (1 - f)[None, :] + g[i0][:, i1] * f[None, :]
    b = g[i1][:, i0] * (1 - f)[None, :] + g[i1][:, i1] * f[None, :]
    return a * (1 - f)[:, None] + b * f[:, None]


def _fbm(rng: np.random.Generator, n: int, octaves: tuple[int, ...]) -> np.ndarray:
    out = np.zeros((n, n))
    for k, c in enumerate(octaves):
        out = out + _smooth_noise(rng, n, c) / (k + 1)
    out = out - out.min()
    return out / max(out.max(), 1e-9)


def _detail(pattern: str, variant: int) -> np.ndarray:
    """(SIZE, SIZE, 3) float multiplier around 1 (the surface colour times this is the texel)."""
    n = SIZE
    rng = _rng(pattern, variant)
    y, x = np.mgrid[0:n, 0:n] / n
    one = np.ones((n, n))
    if pattern == "wood":  # planks along x, grain streaks, per-plank tone, dark seams
        planks = 4
        k = np.floor(y * planks).astype(int)
        tone = 0.8 + 0.4 * rng.random(planks)[k]
        grain = _fbm(rng, n, (4, 16, 64))
        streak = 0.5 + 0.5 * np.sin(2 * np.pi * (y * planks * 6 + 3 * grain))
        v = tone * (0.82 + 0.18 * streak)
        v = np.where(np.abs(y * planks - np.round(y * planks)) < 0.04, 0.45, v)
    elif pattern == "tiles":  # square tiles, light grout, slight tile-to-tile tone
        cells = 4
        kx, ky = np.floor(x * cells).astype(int), np.floor(y * cells).astype(int)
        tone = 0.92 + 0.16 * rng.random((cells, cells))[ky, kx]
        v = tone + 0.05 * (_fbm(rng, n, (32,)) - 0.5)
        grout = (np.abs(x * cells - np.round(x * cells)) < 0.05) | (np.abs(y * cells - np.round(y * cells)) < 0.05)
        v = np.where(grout, 1.25, v)
    elif pattern == "carpet":  # dense fibre noise and soft blotches
        v = 0.75 + 0.35 * rng.random((n, n)) * 0.6 + 0.25 * _fbm(rng, n, (8, 32))
    elif pattern == "plaster":  # painted wall: very low-frequency mottling
        v = 0.92 + 0.12 * _fbm(rng, n, (2, 4, 8)) + 0.03 * rng.random((n, n))
    elif pattern == "fabric":  # woven cloth: crossing threads
        v = 0.8 + 0.12 * np.sin(2 * np.pi * x * 32) ** 2 + 0.12 * np.sin(2 * np.pi * y * 32) ** 2 + 0.1 * _fbm(rng, n, (4, 8))
    elif pattern == "concrete":
        v = 0.75 + 0.3 * _fbm(rng, n, (4, 16, 64)) + 0.08 * rng.random((n, n))
    elif pattern == "brick":  # running bond, mortar joints
        rows = 8
        r = np.floor(y * rows).astype(int)
        xs = (x * 4 + 0.5 * (r % 2)) % 1.0
        tone = 0.8 + 0.35 * rng.random((rows, 4))[r, np.floor((x * 4 + 0.5 * (r % 2)) % 4).astype(int)]
        mortar = (np.abs(y * rows - np.round(y * rows)) < 0.08) | (np.minimum(xs, 1 - xs) < 0.03)
        v = np.where(mortar, 1.35, tone + 0.1 * _fbm(rng, n, (16,)))
    elif pattern == "fur":  # furby: long directional hair streaks
        streak = _fbm(rng, n, (64,))
        v = 0.6 + 0.6 * np.clip(streak + 0.4 * np.sin(2 * np.pi * (x * 40 + 2 * _fbm(rng, n, (4,)))) * 0.5, 0, 1)
    elif pattern == "screen":  # phone: dark bezel, bright app grid on a wallpaper
        v = 0.15 * one
        inner = (x > 0.06) & (x < 0.94) & (y > 0.1) & (y < 0.9)
        wall = 1.0 + 0.7 * _fbm(rng, n, (2, 4))
        v = np.where(inner, wall, v)
        for i in range(4):
            for j in range(6):
                cx, cy = 0.2 + 0.2 * i, 0.18 + 0.12 * j + 0.02
                icon = (np.abs(x - cx) < 0.06) & (np.abs(y - cy) < 0.035)
                v = np.where(icon & inner, 1.6 + 0.8 * rng.random(), v)
        return np.repeat(v[..., None], 3, axis=2)
    elif pattern == "clock_face":  # white dial, hour ticks, two hands
        u, w = x - 0.5, y - 0.5
        r = np.hypot(u, w)
        ang = np.arctan2(w, u)
        v = np.where(r < 0.48, 1.0, 0.3)
        tick = (r > 0.36) & (r < 0.44) & (np.abs(((ang / (2 * np.pi) * 12) + 0.5) % 1 - 0.5) < 0.06)
        v = np.where(tick, 0.08, v)
        h = rng.random(2) * 2 * np.pi
        for a, length, width in ((h[0], 0.25, 0.03), (h[1], 0.38, 0.018)):
            along = u * np.cos(a) + w * np.sin(a)
            across = np.abs(-u * np.sin(a) + w * np.cos(a))
            v = np.where((along > 0) & (along < length) & (across < width), 0.05, v)
        return np.repeat(v[..., None], 3, axis=2)
    elif pattern == "cover":  # book cover: title band and a border
        v = 0.9 + 0.1 * _fbm(rng, n, (8,))
        band = np.abs(y - (0.3 + 0.4 * rng.random())) < 0.08
        v = np.where(band, 1.7, v)
        v = np.where((x < 0.05) | (x > 0.95) | (y < 0.05) | (y > 0.95), 0.5, v)
    elif pattern == "label":  # can / bottle label: a bright band with stripes
        v = np.where(np.abs(y - 0.5) < 0.25, 1.6 + 0.3 * np.sin(2 * np.pi * x * (3 + variant)), 0.8)
    else:  # plain
        v = one
    return np.repeat(v[..., None], 3, axis=2)


@cache
def texture_rgba(pattern: str, variant: int, colour: tuple[float, float, float]) -> np.ndarray:
    """(SIZE, SIZE, 4) uint8 texels of `pattern` variant `variant` tinted by `colour` (linear 0..1)."""
    if pattern not in PATTERNS:
        raise KeyError(f"unknown texture pattern {pattern!r}; known: {', '.join(PATTERNS)}")
    rgb = np.clip(_detail(pattern, variant % VARIANTS) * np.asarray(colour)[None, None, :], 0.0, 1.0)
    out = np.empty((SIZE, SIZE, 4), dtype=np.uint8)
    out[..., :3] = np.round(rgb * 255.0).astype(np.uint8)
    out[..., 3] = 255
    return out


@lru_cache(maxsize=1024)
def render_material(pattern: str, variant: int, colour: tuple[float, float, float], roughness: float) -> sapien.render.RenderMaterial:
    """A SAPIEN material with the texture as base colour ("plain": the colour alone, no texture);
    one GPU texture per key per process."""
    import sapien

    if pattern == "plain":
        return sapien.render.RenderMaterial(base_color=[*colour, 1.0], roughness=roughness)
    mat = sapien.render.RenderMaterial(base_color=[1.0, 1.0, 1.0, 1.0], roughness=roughness)
    mat.base_color_texture = sapien.render.RenderTexture2D(texture_rgba(pattern, variant, colour), "R8G8B8A8Unorm", mipmap_levels=1)
    return mat
