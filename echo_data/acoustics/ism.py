"""Image-source paths inside one room box, with the plan's openings and obstacles.

For a (source, receiver) pair and a lattice cell the path is the straight line from the
image to the receiver, folded back into the box. A path counts when
- each reflection point lies on a solid face (a point inside an open doorway reflects
  nothing; a closed door's leaf reflects with the door's material),
- all reflections happen before the line leaves the box (receivers in other rooms are
  reached only through an opening), and
- no segment crosses a wall or lintel. Closed doors and door leaves on a segment cost
  `door_loss_db` (transmission, see `AcousticScene`); furniture on a segment costs an
  over-the-top edge-diffraction loss (`diffraction_loss_db`).
Everything is vectorised over receivers × image cells so a source's images are computed
once for the whole receiver grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from echo_data.acoustics.geometry import (
    Occluders,
    RoomBox,
    diffraction_loss_db,
    fold,
    mirror,
    segment_box,
    segment_leaf,
)
from echo_data.acoustics.materials import BANDS

_CHUNK_ELEMS = 400_000  # segment×box pairs per vectorised chunk (memory bound)


@dataclass
class Losses:
    """What obstacles do to a set of segments."""

    blocked: np.ndarray  # (n,) bool, a wall or lintel is in the way
    door_db: np.ndarray  # (n,) broadband transmission loss through door panels
    furn_db: np.ndarray  # (n, bands) diffraction loss over furniture


def segment_losses(
    p0: np.ndarray, p1: np.ndarray, occ: Occluders, door_loss_db: float, walls: bool | np.ndarray
) -> Losses:
    """Obstacle effects on segments p0→p1 (n, 3). `walls` (bool or per-segment mask) says
    which segments need the wall/lintel test (segments known to stay inside one room box
    cannot cross a wall)."""
    n = len(p0)
    blocked = np.zeros(n, dtype=bool)
    door_db = np.zeros(n)
    furn_db = np.zeros((n, len(BANDS)))
    live = np.linalg.norm(p1 - p0, axis=1) > 1e-9
    if not live.any():
        return Losses(blocked, door_db, furn_db)
    idx = np.nonzero(live)[0]
    a, b = p0[idx], p1[idx]
    wmask = np.broadcast_to(np.asarray(walls, dtype=bool), (n,))[idx]
    if wmask.any() and len(occ.block_lo):
        wi = np.nonzero(wmask)[0]
        hit, _, _ = segment_box(a[wi], b[wi], occ.block_lo, occ.block_hi)
        blocked[idx[wi]] = hit.any(axis=1)
    n_door = np.zeros(len(idx))
    if len(occ.door_lo):
        hit, _, _ = segment_box(a, b, occ.door_lo, occ.door_hi)
        n_door += hit.sum(axis=1)
    if len(occ.leaf_a):
        n_door += segment_leaf(a, b, occ.leaf_a, occ.leaf_b, occ.leaf_h).sum(axis=1)
    door_db[idx] = n_door * door_loss_db
    if len(occ.furn_lo):
        hit, t_in, t_out = segment_box(a, b, occ.furn_lo, occ.furn_hi)
        si, fi = np.nonzero(hit)
        if len(si):
            d = b[si] - a[si]
            mid = a[si] + 0.5 * (t_in[si, fi] + t_out[si, fi])[:, None] * d
            top = np.column_stack([mid[:, 0], mid[:, 1], occ.furn_hi[fi, 2]])
            delta = np.linalg.norm(top - a[si], axis=1) + np.linalg.norm(b[si] - top, axis=1) - np.linalg.norm(d, axis=1)
            il = np.zeros((len(idx), len(BANDS)))
            np.add.at(il, si, diffraction_loss_db(delta, BANDS))
            furn_db[idx] = il
    return Losses(blocked, door_db, furn_db)


@dataclass
class ImagePaths:
    """Image paths for receivers × cells (arrays over (R, I))."""

    valid: np.ndarray  # (R, I) bool
    length: np.ndarray  # (R, I) path length (m)
    direction: np.ndarray  # (R, I, 3) unit, receiver → image
    log_gain: np.ndarray  # (R, I, bands) natural log of reflection × furniture factors
    door_db: np.ndarray  # (R, I)
    order: np.ndarray  # (I,) reflections
    depart: np.ndarray  # (R, I, 3) unit direction leaving the source


class BoxLattice:
    """The image lattice of one room box up to an order, with per-face reflection factors."""

    def __init__(self, box: RoomBox, order: int, face_log_r: np.ndarray, door_log_r: dict[str, np.ndarray], cells: np.ndarray):
        """face_log_r: (6, bands) log reflection amplitude of faces x-lo, x-hi, y-lo, y-hi, floor, ceiling."""
        self.box = box
        self.cells = cells
        self.order = np.abs(cells).sum(axis=1)
        K = max(int(self.order.max()), 1)
        I = len(cells)
        ax = np.zeros((I, K), dtype=np.int64)
        plane = np.zeros((I, K))
        face = np.zeros((I, K), dtype=np.int64)
        used = np.zeros((I, K), dtype=bool)
        L = box.hi - box.lo
        for i, c in enumerate(cells):
            j = 0
            for a in range(3):
                ks = range(1, c[a] + 1) if c[a] > 0 else range(c[a] + 1, 1)
                for k in ks:
                    ax[i, j], plane[i, j], used[i, j] = a, box.lo[a] + k * L[a], True
                    face[i, j] = 2 * a + (0 if k % 2 == 0 else 1)
                    j += 1
        self.ev_axis, self.ev_plane, self.ev_face, self.ev_used = ax, plane, face, used
        # material table: 0 = no reflection (padding), 1..6 faces, then door panels
        mat_log_r = [np.zeros(len(BANDS)), *face_log_r]
        self.open_mat: list[int] = []
        for op in box.openings:
            if op.closed and op.door_material is not None:
                self.open_mat.append(len(mat_log_r))
                mat_log_r.append(door_log_r[op.door_material])
            else:
                self.open_mat.append(-1)  # no reflection: the path leaves through the opening
        self.mat_log_r = np.asarray(mat_log_r)
        self._local: tuple[int, Occluders] | None = None

    def local(self, occ: Occluders) -> Occluders:
        if self._local is None or self._local[0] != id(occ):
            self._local = (id(occ), occ.local(self.box))
        return self._local[1]

    def trace(
        self,
        src: np.ndarray,
        rcv: np.ndarray,
        occ: Occluders,
        door_loss_db: float,
        walls: bool,
        cell_mask: np.ndarray | None = None,
    ) -> ImagePaths:
        """Paths from sources (3,) or (R, I, 3) to receivers (R, 3) via this box's images.
        `occ` is the whole plan's obstacles; segments inside the box meet only its local ones."""
        R, I = len(rcv), len(self.cells)
        src = np.broadcast_to(np.asarray(src, dtype=np.float64), (R, I, 3))
        out = ImagePaths(
            np.zeros((R, I), dtype=bool),
            np.zeros((R, I)),
            np.zeros((R, I, 3)),
            np.zeros((R, I, len(BANDS))),
            np.zeros((R, I)),
            self.order,
            np.zeros((R, I, 3)),
        )
        K = self.ev_axis.shape[1]
        step = max(1, _CHUNK_ELEMS // max(1, I * (K + 1) * 8))
        for s in range(0, R, step):
            e = min(R, s + step)
            self._trace_chunk(src[s:e], rcv[s:e], occ, door_loss_db, walls, cell_mask, out, s)
        return out

    def _trace_chunk(
        self, src: np.ndarray, rcv: np.ndarray, occ: Occluders, door_loss_db: float, walls: bool, cell_mask: np.ndarray | None, out: ImagePaths, s0: int
    ) -> None:
        box = self.box
        lo, hi = box.lo, box.hi
        R, I, K = len(rcv), len(self.cells), self.ev_axis.shape[1]
        img = mirror(src, self.cells[None], lo, hi)  # (R, I, 3)
        D = rcv[:, None, :] - img
        length = np.linalg.norm(D, axis=2)
        ax = np.broadcast_to(self.ev_axis[None], (R, I, K))
        img_a = np.take_along_axis(img, ax, axis=2)
        D_a = np.take_along_axis(D, ax, axis=2)
        D_a = np.where(np.abs(D_a) < 1e-12, 1e-12, D_a)
        t = (self.ev_plane[None] - img_a) / D_a  # (R, I, K)
        used = np.broadcast_to(self.ev_used[None], (R, I, K))
        ok = np.where(used, (t > 1e-9) & (t < 1.0 - 1e-9), True).all(axis=2)
        pts = fold(img[:, :, None, :] + t[..., None] * D[:, :, None, :], lo, hi)  # (R, I, K, 3)
        # all reflections must happen before the line leaves the box towards an outside receiver
        t_last = np.where(used, t, -np.inf).max(axis=2)
        for a in range(3):
            for plane_v, outside in ((hi[a], rcv[:, a] > hi[a] + 1e-9), (lo[a], rcv[:, a] < lo[a] - 1e-9)):
                if outside.any():
                    t_exit = (plane_v - img[..., a]) / np.where(np.abs(D[..., a]) < 1e-12, 1e-12, D[..., a])
                    ok &= ~(outside[:, None] & (t_last >= t_exit))
        # reflection material per event; openings remove or replace the reflection
        mat = np.where(used, self.ev_face[None] + 1, 0)
        face = np.broadcast_to(self.ev_face[None], (R, I, K))
        for op, m in zip(box.openings, self.open_mat):
            u = pts[..., 1] if op.face in (0, 1) else pts[..., 0]
            inside = used & (face == op.face) & (u > op.u0) & (u < op.u1) & (pts[..., 2] < op.height)
            if m < 0:
                ok &= ~inside.any(axis=2)
            else:
                mat = np.where(inside, m, mat)
        log_gain = self.mat_log_r[mat].sum(axis=2)  # (R, I, bands)
        if cell_mask is not None:
            ok &= cell_mask[None, :]
        # polyline: source, reflection points in path order, receiver
        order_t = np.argsort(np.where(used, t, np.inf), axis=2)
        pts_sorted = np.take_along_axis(pts, order_t[..., None], axis=2)
        used_sorted = np.take_along_axis(used, order_t, axis=2)
        pts_sorted = np.where(used_sorted[..., None], pts_sorted, rcv[:, None, None, :])
        poly = np.concatenate([src[:, :, None, :], pts_sorted, np.broadcast_to(rcv[:, None, None, :], (R, I, 1, 3))], axis=2)
        depart = poly[:, :, 1] - poly[:, :, 0]
        depart /= np.maximum(np.linalg.norm(depart, axis=2, keepdims=True), 1e-12)
        ri = np.nonzero(ok)
        if len(ri[0]):
            segs = poly[ri]  # (n, K+2, 3)
            n = len(segs)
            p0 = segs[:, :-1].reshape(-1, 3)
            p1 = segs[:, 1:].reshape(-1, 3)
            # only the last segment, towards a receiver outside the box, can cross walls
            need = np.zeros((n, K + 1), dtype=bool)
            if walls:
                need[:, -1] = ~box.contains(rcv[ri[0]], 1e-6)
                # padding repeats the receiver, so the real last segment may sit earlier
                nev = used.sum(axis=2)[ri]
                need[np.arange(n), nev] = need[:, -1]
            need = need.reshape(-1)
            blocked = np.zeros(len(p0), dtype=bool)
            door = np.zeros(len(p0))
            furn = np.zeros((len(p0), len(BANDS)))
            for sel, o in ((~need, self.local(occ)), (need, occ)):
                if sel.any():
                    los = segment_losses(p0[sel], p1[sel], o, door_loss_db, True)
                    blocked[sel], door[sel], furn[sel] = los.blocked, los.door_db, los.furn_db
            blocked = blocked.reshape(n, K + 1).any(axis=1)
            door = door.reshape(n, K + 1).sum(axis=1)
            furn = np.minimum(furn.reshape(n, K + 1, -1).sum(axis=1), 40.0)
            ok[ri] = ~blocked
            out.door_db[s0 + ri[0], ri[1]] = door
            log_gain[ri] -= furn * (np.log(10.0) / 20.0)
        sl = slice(s0, s0 + R)
        out.valid[sl] = ok
        out.length[sl] = length
        out.direction[sl] = -D / np.maximum(length[..., None], 1e-12)
        out.log_gain[sl] = log_gain
        out.depart[sl] = depart
