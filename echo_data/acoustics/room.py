"""The geometric acoustic scene: a `FloorPlan` → per-(source, receiver) `AcousticResponse`s.

Early part (directional `arrivals`):
- image sources of the source's room (shoebox lattice up to `cfg.ism_order`) with
  reflection points checked against doorways and segments against walls, lintels,
  door panels and furniture (see `echo_data.acoustics.ism`);
- sound into other rooms through doorways: a secondary source in the opening at the point
  of the shortest path (geometric when the line passes through the opening, else an edge
  diffraction with the Kurze–Anderson loss of its detour), followed by that room's own
  image sources; rooms further away chain through the doorway centres on the shortest
  route. The secondary direct path is dropped where the geometric direct path exists.
- Doors: a closed leaf (hinge angle < 6°) seals its doorway; every path through it is a
  transmission ("leak") path with `cfg.closed_door_loss_db` broadband loss (order -1 when it
  would otherwise be the direct path; reflections keep their order) and the leaf reflects
  like a door panel. An open leaf is a thin panel at its hinge angle: paths crossing it
  take the same transmission loss; reflections off open leaves are not modelled.
- Furniture: solid blocks that occlude (over-the-top diffraction loss on each path through
  them), absorb (their surfaces join the room's absorption) and reflect off their tops
  (first order, source room); side faces do not reflect.
- Per reflection the specular amplitude is sqrt((1 - alpha)(1 - s)) per band (material from
  pyroomacoustics' database, s = `cfg.scattering`); air absorption over the path length.

Late part (`tail`): statistical, see `echo_data.acoustics.tail` (`cfg.rays` is not used:
a statistical tail is deterministic, cheap per receiver and, with scattering, matches
Sabine/Eyring, where pyroomacoustics' ray tracer costs grow with the receiver count).

Why our own image sources rather than pyroomacoustics' polygon ISM: see
`echo_data.acoustics.geometry`. Cost: a source's lattice, routes and room energies are
computed once per `responses` call and vectorised over all receivers.

Points inside a wall (grid cells on wall lines) are taken 1 cm inside the nearest room.
Wall, floor and ceiling materials are the room's (`Room.*_material`); doors use
`Door.material`, furniture `Furniture.material`.
"""

from __future__ import annotations

import hashlib
import heapq
import math
from dataclasses import dataclass

import numpy as np

from echo_data.acoustics.arrivals import PathSet, omni_rir
from echo_data.acoustics.geometry import (
    Opening,
    RoomBox,
    diffraction_loss_db,
    image_cells,
    occluders,
    opening_solid_angle,
    room_boxes,
)
from echo_data.acoustics.ism import BoxLattice, ImagePaths, segment_losses
from echo_data.acoustics.materials import BANDS, absorption, air_absorption, reflection_amplitude
from echo_data.acoustics.tail import NoiseBank, RoomAcoustics, scattered_share
from echo_data.acoustics.types import SPEED_OF_SOUND, AcousticResponse, ApertureTail, Arrival
from echo_data.floorplan import FloorPlan
from echo_data.recipe import AcousticsConfig

__all__ = ["AcousticScene", "omni_rir"]  # omni_rir: rendered in acoustics.arrivals, long imported from here
Vec3 = tuple[float, float, float]
_FACE_INSET = 0.01  # secondary sources sit 1 cm inside the room faces of a doorway
_EDGE_MARGIN = 0.05  # and at least 5 cm from the jambs and the lintel
_APERTURE_POINTS = (1 / 6, 1 / 2, 5 / 6)  # across an opening's width: its late energy's directions


@dataclass
class _Hub:
    """A point on the shortest doorway route from the source room into a room."""

    point: np.ndarray  # (3,) where sound enters the room (doorway centre, inside the face)
    length: float  # path length from the source to `point`
    log_gain: np.ndarray  # (bands,) diffraction losses on the way (natural log, amplitude)
    door_db: float
    prev: np.ndarray  # (3,) previous point on the route (for the diffraction angle)


@dataclass
class _Entry:
    """A doorway through which sound enters room `room` from the hub of room `frm`."""

    room: int
    frm: int
    opening: Opening  # as seen from `room`


class AcousticScene:
    """Acoustic model of one floor plan with fixed door angles (rad, by door index)."""

    def __init__(self, plan: FloorPlan, cfg: AcousticsConfig, door_angles: dict[int, float] | None = None):
        self.plan = plan
        self.cfg = cfg
        self.fs = int(cfg.sample_rate)
        self.length = int(round(cfg.rir_seconds * self.fs))
        self.door_angles = {d.index: float(d.angle) for d in plan.doors}
        self.door_angles.update({int(k): float(v) for k, v in (door_angles or {}).items()})
        self.boxes: list[RoomBox] = room_boxes(plan, self.door_angles)
        self.occ = occluders(plan, self.door_angles)
        self.air = air_absorption() if cfg.air_absorption else np.zeros(len(BANDS))
        self.acoustics = RoomAcoustics(plan, self.boxes, cfg.closed_door_loss_db)
        self.noise = NoiseBank(self.fs, self.length, plan.seed)
        self._tail_base: dict[int, np.ndarray] = {}  # source room -> (rooms, bands, length) amplitudes
        # the tail ends within the RIR length: a 20 ms raised-cosine fade instead of a cut
        n_fade = max(1, min(self.length // 4, int(0.02 * self.fs)))
        self._fade_out = np.cos(0.5 * np.pi * (np.arange(n_fade) + 1) / n_fade) ** 2
        cells = image_cells(cfg.ism_order)
        s = cfg.scattering
        door_log_r = {
            d.material: np.log(reflection_amplitude(absorption(d.material), s)) for d in plan.doors
        }
        self.lattices: list[BoxLattice] = []
        for box in self.boxes:
            r = box.room
            face = [absorption(r.wall_material)] * 4 + [absorption(r.floor_material), absorption(r.ceiling_material)]
            log_r = np.log(np.asarray([reflection_amplitude(a, s) for a in face]))
            self.lattices.append(BoxLattice(box, cfg.ism_order, log_r, door_log_r, cells))

    # ------------------------------------------------------------------ public API
    def room_of(self, p: Vec3 | np.ndarray) -> int:
        """Index (into plan.rooms) of the room box containing p, else the nearest one."""
        q = np.asarray(p, dtype=np.float64)
        d = [float(np.linalg.norm(np.maximum(b.lo - q, 0.0) + np.maximum(q - b.hi, 0.0))) for b in self.boxes]
        return int(np.argmin(d))

    def _rooms_of(self, pts: np.ndarray) -> np.ndarray:
        """Vectorised `room_of` for points (n, 3)."""
        lo = np.stack([b.lo for b in self.boxes])[None]
        hi = np.stack([b.hi for b in self.boxes])[None]
        p = pts[:, None, :]
        d = np.linalg.norm(np.maximum(lo - p, 0.0) + np.maximum(p - hi, 0.0), axis=2)
        return np.argmin(d, axis=1)

    def _into_room(self, pts: np.ndarray, rooms: np.ndarray) -> np.ndarray:
        lo = np.stack([self.boxes[r].lo for r in rooms])
        hi = np.stack([self.boxes[r].hi for r in rooms])
        inside = np.all((pts >= lo) & (pts <= hi), axis=1)
        m = np.minimum(0.01, 0.25 * (hi - lo))
        return np.where(inside[:, None], pts, np.clip(pts, lo + m, hi - m))

    def free_field(self, source: Vec3, receiver: Vec3) -> AcousticResponse:
        """Direct sound only (no room), for tests and as a reference for the binaural stage."""
        s, r = np.asarray(source, dtype=np.float64), np.asarray(receiver, dtype=np.float64)
        d = max(float(np.linalg.norm(s - r)), 1e-3)
        band = np.exp(-0.5 * self.air * d)
        u = (s - r) / d
        arr = Arrival(d / SPEED_OF_SOUND, (float(u[0]), float(u[1]), float(u[2])), 1.0 / d, tuple(float(v) for v in band), 0)
        return AcousticResponse(self.fs, [arr], np.zeros(self.length, dtype=np.float32), self.length)

    def response(self, source: Vec3, receiver: Vec3) -> AcousticResponse:
        """Response from one source to one receiver."""
        return self.responses(source, np.asarray([receiver], dtype=np.float64))[0]

    def responses(self, source: Vec3, receivers: np.ndarray) -> list[AcousticResponse]:
        """Responses from one source to many receivers (n, 3); the source's image sources,
        routes and room energies are computed once for all of them."""
        S0 = np.asarray(source, dtype=np.float64)
        rcv0 = np.asarray(receivers, dtype=np.float64).reshape(-1, 3)
        n = len(rcv0)
        if n == 0:
            return []
        a_room = self.room_of(S0)
        rooms = self._rooms_of(rcv0)
        # a point inside a wall (e.g. a grid cell on a wall line) is taken at the nearest
        # room's face, 1 cm into the room: a head or a sound source cannot sit in a wall
        S = self._into_room(S0[None], np.asarray([a_room]))[0]
        rcv = self._into_room(rcv0, rooms)
        c = SPEED_OF_SOUND
        max_len = self.length / self.fs * c

        paths = PathSet()
        # 1) image sources of the source room, for every receiver
        lat = self.lattices[a_room]
        ip = lat.trace(S, rcv, self.occ, self.cfg.closed_door_loss_db, walls=True)
        # a geometric direct path (possibly through a door panel) makes the doorway's
        # secondary direct path redundant
        direct_ok = ip.valid[:, 0].copy()
        paths.add(np.arange(n), ip, np.zeros(ip.log_gain.shape), 0.0, np.zeros(ip.length.shape), None)
        for fp in self._furniture_tops(S, rcv, rooms, a_room):
            paths.add(np.arange(n), fp, np.zeros(fp.log_gain.shape), 0.0, np.zeros(fp.length.shape), None)

        # 2) through doorways into the other rooms
        hubs, entries = self._routes(S, a_room)
        onset = np.full(n, np.inf)
        in_a = rooms == a_room
        onset[in_a] = np.linalg.norm(rcv[in_a] - S, axis=1) / c
        for e in entries:
            sel = np.nonzero(rooms == e.room)[0]
            if len(sel) == 0:
                continue
            t_on = self._entry_paths(paths, sel, rcv[sel], e, hubs[e.frm], direct_ok[sel])
            onset[sel] = np.minimum(onset[sel], t_on)

        # 3) assemble
        per_row = paths.arrivals(n, self.air, max_len)
        base = self._tail_amplitudes(a_room)
        mix = self._aperture_mix(rcv, rooms)
        out: list[AcousticResponse] = []
        qs = [int(round(v * 1000.0)) for v in S0]
        for i in range(n):
            x = rooms[i]
            key = (self.plan.seed, *qs, *(int(round(v * 1000.0)) for v in rcv0[i]))
            own = 1.0 - sum(h for _, h, _ in mix[i])
            tail = np.zeros(self.length, dtype=np.float32)
            apertures: list[ApertureTail] = []
            if np.isfinite(onset[i]):
                if base[x].any():
                    tail = self._tail(base[x] * math.sqrt(own), float(onset[i]), self.noise.segment(key))
                for j, (y, h, pts) in enumerate(mix[i]):
                    if not base[y].any():
                        continue
                    amp = base[y] * math.sqrt(h / len(pts))
                    sig = [self._tail(amp, float(onset[i]), self.noise.segment((*key, j + 1, m + 1))) for m in range(len(pts))]
                    dirs = pts - rcv[i]
                    dirs /= np.maximum(np.linalg.norm(dirs, axis=1, keepdims=True), 1e-9)
                    apertures.append(ApertureTail(dirs, np.stack(sig)))
            seed = int.from_bytes(hashlib.blake2b(np.asarray(key, dtype=np.int64).tobytes(), digest_size=8).digest(), "little")
            out.append(AcousticResponse(self.fs, per_row[i], tail, self.length, field_seed=seed, apertures=apertures))
        return out

    def _aperture_mix(self, rcv: np.ndarray, rooms: np.ndarray) -> list[list[tuple[int, float, np.ndarray]]]:
        """Per receiver, the openings through which it hears a neighbouring room's diffuse
        field (see `echo_data.acoustics.tail`): (neighbour room, weight h, (k, 3) points spread
        over the opening, the extended source's directions); openings with h < 1e-3 are left out."""
        out: list[list[tuple[int, float, np.ndarray]]] = [[] for _ in range(len(rcv))]
        for x, box in enumerate(self.boxes):
            sel = np.nonzero(rooms == x)[0]
            if len(sel) == 0:
                continue
            for op in box.openings:
                if op.other_room < 0:
                    continue
                a = 0 if op.face in (0, 1) else 1
                other = self.boxes[op.other_room]
                face_x = box.lo[a] if op.face in (0, 2) else box.hi[a]
                face_y = other.hi[a] if op.face in (0, 2) else other.lo[a]
                plane = 0.5 * (face_x + face_y)
                h = opening_solid_angle(rcv[sel], op, plane) / (4.0 * math.pi)
                h *= self.acoustics.transfer_share[(x, op.doorway)]
                pts = np.zeros((len(_APERTURE_POINTS), 3))
                pts[:, a] = plane
                pts[:, 1 - a] = op.u0 + np.asarray(_APERTURE_POINTS) * (op.u1 - op.u0)
                pts[:, 2] = 0.5 * op.height
                for i, hv in zip(sel.tolist(), h.tolist()):
                    if hv > 1e-3:
                        out[i].append((int(op.other_room), float(hv), pts))
        for parts in out:
            total = sum(h for _, h, _ in parts)
            if total > 0.5:  # openings on several sides: never more than half-space
                parts[:] = [(y, h * 0.5 / total, p) for y, h, p in parts]
        return out

    def _tail_amplitudes(self, a_room: int) -> np.ndarray:
        """Per room and band, the tail's amplitude envelope for a source in `a_room`."""
        if a_room not in self._tail_base:
            env = self.acoustics.energy_envelopes(a_room, self.fs, self.length)
            t = np.arange(self.length) / self.fs
            for x in range(len(self.boxes)):
                env[x] *= scattered_share(t, float(self.acoustics.mean_free_path[x]), self.cfg.scattering, self.cfg.ism_order)[None]
            self._tail_base[a_room] = np.sqrt(env)
        return self._tail_base[a_room]

    def _tail(self, amp: np.ndarray, t0: float, noise: np.ndarray) -> np.ndarray:
        """Band noise under the amplitude envelope `amp` (bands, length), gated on at t0 (s)."""
        x = np.einsum("bt,bt->t", amp, noise)
        i0 = int(math.floor(t0 * self.fs))
        x[: max(i0, 0)] = 0.0
        ramp = np.clip((np.arange(i0, i0 + 17) / self.fs - t0) * self.fs / 16.0, 0.0, 1.0)
        seg = slice(max(i0, 0), min(i0 + 17, self.length))
        x[seg] *= np.sin(0.5 * np.pi * ramp[seg.start - i0 : seg.stop - i0]) ** 2
        x[-len(self._fade_out) :] *= self._fade_out
        return x.astype(np.float32)

    # ------------------------------------------------------------------ internals
    def _furniture_tops(self, S: np.ndarray, rcv: np.ndarray, rooms: np.ndarray, a_room: int) -> list[ImagePaths]:
        """First-order specular reflections off the tops of the source room's furniture
        (a phone on a table is heard with the table's reflection); side faces are not
        modelled as reflectors."""
        out: list[ImagePaths] = []
        box = self.boxes[a_room]
        outside = rooms != a_room
        for f in self.plan.furniture:
            fp = f.footprint
            top = f.top_z
            if S[2] <= top + 1e-6 or fp.xmax <= box.lo[0] or fp.xmin >= box.hi[0] or fp.ymax <= box.lo[1] or fp.ymin >= box.hi[1]:
                continue
            img = np.array([S[0], S[1], 2.0 * top - S[2]])
            D = rcv - img
            dz = np.where(np.abs(D[:, 2]) < 1e-12, 1e-12, D[:, 2])
            t = (top - img[2]) / dz
            P = img + t[:, None] * D
            ok = (rcv[:, 2] > top + 1e-6) & (P[:, 0] > fp.xmin) & (P[:, 0] < fp.xmax) & (P[:, 1] > fp.ymin) & (P[:, 1] < fp.ymax)
            length = np.linalg.norm(D, axis=1)
            log_r = np.log(reflection_amplitude(absorption(f.material), self.cfg.scattering))
            door = np.zeros(len(rcv))
            furn = np.zeros((len(rcv), len(BANDS)))
            idx = np.nonzero(ok)[0]
            if len(idx):
                loss_db = self.cfg.closed_door_loss_db
                leg1 = segment_losses(np.broadcast_to(S, (len(idx), 3)), P[idx], self.lattices[a_room].local(self.occ), loss_db, False)
                leg2 = segment_losses(P[idx], rcv[idx], self.occ, loss_db, outside[idx])
                ok[idx] = ~(leg1.blocked | leg2.blocked)
                door[idx] = leg1.door_db + leg2.door_db
                furn[idx] = np.minimum(leg1.furn_db + leg2.furn_db, 40.0)
            out.append(
                ImagePaths(
                    ok[:, None],
                    length[:, None],
                    (-D / np.maximum(length[:, None], 1e-12))[:, None, :],
                    (log_r[None] - furn * (math.log(10.0) / 20.0))[:, None, :],
                    door[:, None],
                    np.ones(1, dtype=np.int64),
                    np.zeros((len(rcv), 1, 3)),
                )
            )
        return out

    def _doorway_points(self, op: Opening, frm: int, to: int, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points just inside the two faces of a doorway at lateral/vertical position of p."""
        a = 0 if op.face in (0, 1) else 1  # normal axis
        fa = self.boxes[frm].hi[a] if op.face in (0, 2) else self.boxes[frm].lo[a]
        fb = self.boxes[to].lo[a] if op.face in (0, 2) else self.boxes[to].hi[a]
        sgn = 1.0 if op.face in (0, 2) else -1.0  # from `frm` into `to` along the normal
        pa, pb = p.copy(), p.copy()
        pa[..., a] = fa - sgn * _FACE_INSET
        pb[..., a] = fb + sgn * _FACE_INSET
        return pa, pb

    def _clamp_in_opening(self, op: Opening, p: np.ndarray) -> np.ndarray:
        u_axis = 1 if op.face in (0, 1) else 0
        q = p.copy()
        w = op.u1 - op.u0
        m = min(_EDGE_MARGIN, 0.25 * w)
        q[..., u_axis] = np.clip(q[..., u_axis], op.u0 + m, op.u1 - m)
        q[..., 2] = np.clip(q[..., 2], _EDGE_MARGIN, op.height - _EDGE_MARGIN)
        return q

    def _routes(self, S: np.ndarray, a_room: int) -> tuple[dict[int, _Hub], list[_Entry]]:
        """Shortest doorway routes (Dijkstra over doorway centres) from the source room."""
        hubs = {a_room: _Hub(S.copy(), 0.0, np.zeros(len(BANDS)), 0.0, S.copy())}
        dist = {a_room: 0.0}
        heap = [(0.0, a_room)]
        done: set[int] = set()
        entries: list[_Entry] = []
        while heap:
            _, y = heapq.heappop(heap)
            if y in done:
                continue
            done.add(y)
            hub = hubs[y]
            for op in self.boxes[y].openings:
                x = op.other_room
                if x < 0 or x in done:
                    continue
                op_x = next(o for o in self.boxes[x].openings if o.doorway == op.doorway)
                entries.append(_Entry(x, y, op_x))
                centre = self._clamp_in_opening(op_x, self._opening_centre(op_x, hub.point[2]))
                pa, pb = self._doorway_points(op_x, y, x, centre)
                los = segment_losses(
                    np.stack([hub.point, pa]), np.stack([pa, pb]), self.occ, self.cfg.closed_door_loss_db, False
                )
                L = hub.length + float(np.linalg.norm(pa - hub.point) + np.linalg.norm(pb - pa))
                if x not in dist or dist[x] > L:
                    lg = hub.log_gain.copy()
                    if y != a_room:  # diffraction at the hub towards this doorway
                        lg -= self._diff_db(hub.prev, hub.point, pb, hub.length) * (math.log(10) / 20)
                    lg -= los.furn_db.sum(axis=0) * (math.log(10) / 20)
                    dist[x] = L
                    hubs[x] = _Hub(pb, L, lg, hub.door_db + float(los.door_db.sum()), hub.point)
                    heapq.heappush(heap, (L, x))
        # keep only entries whose upstream room was reached before the room itself
        entries = [e for e in entries if dist[e.frm] < dist[e.room]]
        return hubs, entries

    @staticmethod
    def _opening_centre(op: Opening, z: float) -> np.ndarray:
        u = 0.5 * (op.u0 + op.u1)
        return np.array([0.0, u, z]) if op.face in (0, 1) else np.array([u, 0.0, z])

    @staticmethod
    def _diff_db(q: np.ndarray, p: np.ndarray, nxt: np.ndarray, a_len: float | None = None) -> np.ndarray:
        a = float(np.linalg.norm(p - q)) if a_len is None else max(a_len, 1e-6)
        b = float(np.linalg.norm(nxt - p))
        din = (p - q) / max(float(np.linalg.norm(p - q)), 1e-12)
        dout = (nxt - p) / max(b, 1e-12)
        cos = float(np.dot(din, dout))
        delta = a + b - math.sqrt(max(a * a + b * b + 2 * a * b * cos, 0.0))
        return diffraction_loss_db(np.asarray(delta), BANDS)

    def _entry_paths(self, paths: PathSet, rows: np.ndarray, rcv: np.ndarray, e: _Entry, hub: _Hub, direct_ok: np.ndarray) -> np.ndarray:
        """Secondary-source paths through doorway `e` for receivers of its room; returns the
        earliest arrival time per receiver (the tail onset)."""
        op = e.opening
        x_box = self.boxes[e.room]
        lat = self.lattices[e.room]
        cells = lat.cells
        a = 0 if op.face in (0, 1) else 1
        # only images on the room's side of the doorway: paths leave the doorway into the room
        cmask = cells[:, a] >= 0 if op.face in (0, 2) else cells[:, a] <= 0
        R, I = len(rcv), len(cells)
        # receiver images by the inverse cell map, then the shortest-path point in the opening
        inv = np.where(cells % 2 == 0, -cells, cells)
        Lx = x_box.hi - x_box.lo
        u = rcv[:, None, :] - x_box.lo
        r_img = x_box.lo + inv[None] * Lx + np.where(inv[None] % 2 == 0, u, Lx - u)  # (R, I, 3)
        Q = hub.point
        plane = 0.5 * (self.boxes[e.frm].hi[a] + x_box.lo[a]) if op.face in (0, 2) else 0.5 * (self.boxes[e.frm].lo[a] + x_box.hi[a])
        den = r_img[..., a] - Q[a]
        den = np.where(np.abs(den) < 1e-9, 1e-9, den)
        t = np.clip((plane - Q[a]) / den, 0.0, 1.0)
        p = Q + t[..., None] * (r_img - Q)
        p = self._clamp_in_opening(op, p)
        pa, pb = self._doorway_points(op, e.frm, e.room, p)
        ip = lat.trace(pb, rcv, self.occ, self.cfg.closed_door_loss_db, walls=False, cell_mask=cmask)
        # legs hub → doorway (inside the upstream room) and through the doorway
        # (only for paths still valid: the hub leg stays in the upstream room)
        vr, vi = np.nonzero(ip.valid)
        loss_db = self.cfg.closed_door_loss_db
        hub_leg = segment_losses(
            np.broadcast_to(Q, (len(vr), 3)), pa[vr, vi], self.lattices[e.frm].local(self.occ), loss_db, False
        )
        door_leg = segment_losses(pa[vr, vi], pb[vr, vi], self.occ, loss_db, False)
        leg_door = np.zeros((R, I))
        leg_furn = np.zeros((R, I, len(BANDS)))
        leg_door[vr, vi] = hub_leg.door_db + door_leg.door_db
        leg_furn[vr, vi] = hub_leg.furn_db + door_leg.furn_db
        a_len = np.linalg.norm(pa - Q, axis=2) + np.linalg.norm(pb - pa, axis=2)
        # edge diffraction at the doorway point: detour against the straight continuation
        din = (pb - Q) / np.maximum(np.linalg.norm(pb - Q, axis=2, keepdims=True), 1e-12)
        cos = np.sum(din * ip.depart, axis=2)
        A = hub.length + a_len  # unfolded distance from the source to the doorway point
        B = ip.length
        delta = A + B - np.sqrt(np.maximum(A * A + B * B + 2 * A * B * cos, 0.0))
        il = diffraction_loss_db(delta, BANDS) + leg_furn
        log0 = hub.log_gain[None, None] - il * (math.log(10.0) / 20.0)
        ip.door_db = ip.door_db + leg_door
        total_len = hub.length + a_len
        ip.door_db = ip.door_db + hub.door_db
        paths.add(rows, ip, log0, 0.0, total_len, direct_ok)
        first = np.where(ip.valid, total_len + ip.length, np.inf).min(axis=1)
        # (a receiver no path reaches still gets its tail from the doorway centre on)
        mid_a, mid_b = self._doorway_points(op, e.frm, e.room, self._clamp_in_opening(op, self._opening_centre(op, float(Q[2]))))
        centre = hub.length + np.linalg.norm(mid_a - Q) + np.linalg.norm(mid_b - mid_a) + np.linalg.norm(rcv - mid_b, axis=1)
        return np.minimum(first, centre) / SPEED_OF_SOUND
