"""Visual triangle meshes with texture coordinates, built with numpy (no mesh files).

SAPIEN's primitive visuals map a texture once per face, which stretches a plank or a tile over
a whole 5 m floor; these meshes carry UVs in metres / repeat length instead, so a texture
tiles at its real size. Spheres and cylinders get UVs that wrap once around them (fur, a label).
Meshes are visual only: collision shapes stay the boxes and primitives of the callers.

Each builder returns (vertices (n,3) f32, triangles (m,3) u32, normals (n,3) f32, uvs (n,2) f32).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

Mesh = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _pack(v: list, t: list, n: list, uv: list) -> Mesh:
    return (np.asarray(v, np.float32), np.asarray(t, np.uint32), np.asarray(n, np.float32), np.asarray(uv, np.float32))


@lru_cache(maxsize=4096)
def box(half: tuple[float, float, float], period: float | None = None) -> Mesh:
    """A box of half sizes `half`; UVs repeat every `period` metres, or span each face once (None)."""
    hx, hy, hz = half
    verts: list[list[float]] = []
    tris: list[list[int]] = []
    norms: list[list[float]] = []
    uvs: list[list[float]] = []
    # (normal axis, sign): the two in-plane axes (u, v) chosen so triangles wind outwards
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u_ax, v_ax = [(1, 2), (2, 0), (0, 1)][axis]
            if sign < 0:
                u_ax, v_ax = v_ax, u_ax
            h = (hx, hy, hz)
            base = len(verts)
            for cu, cv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = [0.0, 0.0, 0.0]
                p[axis] = sign * h[axis]
                p[u_ax] = cu * h[u_ax]
                p[v_ax] = cv * h[v_ax]
                verts.append(p)
                nv = [0.0, 0.0, 0.0]
                nv[axis] = sign
                norms.append(nv)
                if period is None:
                    uvs.append([(cu + 1) / 2.0, (1 - cv) / 2.0])
                else:
                    uvs.append([p[u_ax] / period, p[v_ax] / period])
            tris += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
    return _pack(verts, tris, norms, uvs)


@lru_cache(maxsize=256)
def ellipsoid(radii: tuple[float, float, float], segments: int = 16) -> Mesh:
    """A UV sphere scaled to `radii`; u wraps once around z, v runs pole to pole."""
    rings = segments // 2
    th = np.linspace(0.0, np.pi, rings + 1)
    ph = np.linspace(0.0, 2 * np.pi, segments + 1)
    T, P = np.meshgrid(th, ph, indexing="ij")
    unit = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1).reshape(-1, 3)
    r = np.asarray(radii)
    v = unit * r
    n = unit / r
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    uv = np.stack([P / (2 * np.pi) * 2.0, T / np.pi], axis=-1).reshape(-1, 2)
    tris = []
    w = segments + 1
    for i in range(rings):
        for j in range(segments):
            a, b = i * w + j, (i + 1) * w + j
            tris += [[a, b, b + 1], [a, b + 1, a + 1]]
    return _pack(v, tris, n, uv)


@lru_cache(maxsize=256)
def cylinder(radius: float, half_height: float, segments: int = 20) -> Mesh:
    """An upright (z) capped cylinder; the side's u wraps once around, caps map a disc to [0,1]²."""
    ph = np.linspace(0.0, 2 * np.pi, segments + 1)
    c, s = np.cos(ph), np.sin(ph)
    verts, norms, uvs, tris = [], [], [], []
    for k in range(segments + 1):
        for z, vv in ((-half_height, 1.0), (half_height, 0.0)):
            verts.append([radius * c[k], radius * s[k], z])
            norms.append([c[k], s[k], 0.0])
            uvs.append([k / segments, vv])
    for k in range(segments):
        a = 2 * k
        tris += [[a, a + 2, a + 3], [a, a + 3, a + 1]]
    for z, sign in ((half_height, 1.0), (-half_height, -1.0)):
        centre = len(verts)
        verts.append([0.0, 0.0, z])
        norms.append([0.0, 0.0, sign])
        uvs.append([0.5, 0.5])
        for k in range(segments + 1):
            verts.append([radius * c[k], radius * s[k], z])
            norms.append([0.0, 0.0, sign])
            uvs.append([0.5 + 0.5 * c[k], 0.5 - 0.5 * s[k]])
        for k in range(segments):
            a, b = centre + 1 + k, centre + 2 + k
            tris.append([centre, a, b] if sign > 0 else [centre, b, a])
    return _pack(verts, tris, norms, uvs)


def rotated(mesh: Mesh, rot: np.ndarray, offset: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Mesh:
    """`mesh` rotated by the 3x3 `rot` and moved by `offset`."""
    v, t, n, uv = mesh
    return ((v @ rot.T + np.asarray(offset)).astype(np.float32), t, (n @ rot.T).astype(np.float32), uv)
