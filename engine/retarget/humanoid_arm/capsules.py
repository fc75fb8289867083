"""Self-collision by capsules (§III): one capsule per upper-body link group, fitted to the robot's
collision meshes; signed distance = segment–segment distance − (r1 + r2); a pose fixer that pushes
colliding links apart through the Jacobian until every signed distance is ≥ 0.

Fitting: the capsule axis is the principal axis of the group's collision-hull vertices; the radius the
largest distance of a vertex from that axis; the segment ends the tightest ones that still enclose every
vertex. Capsules therefore contain the meshes MuJoCo collides (conservative: whenever MuJoCo reports a
contact between two groups, their capsules overlap — :func:`mujoco_agreement` measures it).

Pairs checked: every two groups except neighbours in the kinematic chain and pairs whose capsules
overlap in almost every pose (≥ 95 % of random poses: they touch by construction, e.g. shoulder and
upper arm).

Distances run in C++: the capsules are coal (hpp-fcl) capsules in a pinocchio GeometryModel over the
same pairs, so one collision check is one ``computeDistances`` call (≈ 10 µs; the vectorised numpy
:func:`segment_distance` gives the same numbers to 1e-15 and stays the reference and the fixer's
closest-point routine).

The fixer follows the paper with one change: it moves the closest points of a colliding pair apart
along their separating direction (the paper uses the capsules' centres), solved by damped least
squares through the point Jacobians, with a backtracking step so total penetration never increases.
"""

from __future__ import annotations

import operator
from dataclasses import dataclass

import coal
import mujoco
import numpy as np
import pinocchio as pin

from engine.retarget.humanoid_arm.upper_body import UpperBody

ALWAYS_TOUCHING_FRACTION = 0.95
_MIN_DISTANCE = operator.attrgetter("min_distance")


# ----------------------------------------------------------------------------- geometry


def segment_distance(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray):
    """Closest points between segments p1–q1 and p2–q2, vectorised over leading axes (Ericson, RTCD §5.1.9).

    Returns (distance, c1, c2)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    dot = lambda u, v: np.einsum("...i,...i->...", u, v)  # noqa: E731
    a, e, f, c, b = dot(d1, d1), dot(d2, d2), dot(d2, r), dot(d1, r), dot(d1, d2)
    eps = 1e-12
    denom = a * e - b * b
    # parallel only when the angle between them is below ~3e-7 rad: a threshold relative to a·e, not absolute
    # (two perpendicular segments of 6e-5 m and 1.6 cm have a·e − b² ≈ 1e-12 and met at a point, but an
    # absolute 1e-12 took them for parallel and returned 6e-5 m), and small (at 3e-5 rad two 1 m segments
    # crossing in an X were taken for parallel and 6e-6 m apart). a·e − b² loses ~1e-16·a·e to cancellation.
    skew = denom > 1e-13 * a * e
    s = np.where(skew, np.clip((b * f - c * e) / np.where(skew, denom, 1.0), 0.0, 1.0), 0.0)
    t = np.where(e > eps, (b * s + f) / np.where(e > eps, e, 1.0), 0.0)
    # t outside [0, 1]: clamp t and recompute s
    s = np.where(t < 0.0, np.clip(-c / np.where(a > eps, a, 1.0), 0.0, 1.0), s)
    s = np.where(t > 1.0, np.clip((b - c) / np.where(a > eps, a, 1.0), 0.0, 1.0), s)
    t = np.clip(t, 0.0, 1.0)
    # degenerate segments (points): Ericson's special cases
    safe_a = np.where(a > eps, a, 1.0)
    s = np.where(e <= eps, np.clip(-c / safe_a, 0.0, 1.0), s)
    t = np.where(e <= eps, 0.0, t)
    t = np.where(a <= eps, np.clip(f / np.where(e > eps, e, 1.0), 0.0, 1.0), t)
    s = np.where(a > eps, s, 0.0)
    c1 = p1 + s[..., None] * d1
    c2 = p2 + t[..., None] * d2
    dist = np.linalg.norm(c1 - c2, axis=-1)
    if np.all(skew):
        return dist, c1, c2
    # (nearly) parallel pairs: s = 0 is only one of the minimisers when they overlap; when they do not, the
    # closest pair has an end point on one side (two antiparallel segments sharing an end met at 6e-6 m from
    # s = 0). The minimum over the four end-point-to-segment distances is exact for parallel segments.
    candidates = [
        (p1, _closest_on_segment(p1, p2, d2, e, eps)),
        (q1, _closest_on_segment(q1, p2, d2, e, eps)),
        (_closest_on_segment(p2, p1, d1, a, eps), p2),
        (_closest_on_segment(q2, p1, d1, a, eps), q2),
    ]
    for x1, x2 in candidates:
        dx = np.linalg.norm(x1 - x2, axis=-1)
        better = ~skew & (dx < dist)
        dist = np.where(better, dx, dist)
        c1 = np.where(better[..., None], x1, c1)
        c2 = np.where(better[..., None], x2, c2)
    return dist, c1, c2


def _closest_on_segment(x: np.ndarray, p: np.ndarray, d: np.ndarray, dd: np.ndarray, eps: float) -> np.ndarray:
    """The point of segment p + u·d (u ∈ [0, 1], dd = d·d) closest to x, vectorised like segment_distance."""
    u = np.clip(np.einsum("...i,...i->...", x - p, d) / np.where(dd > eps, dd, 1.0), 0.0, 1.0)
    u = np.where(dd > eps, u, 0.0)
    return p + u[..., None] * d


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (N, 3) arrays (np.cross's numbers, a fraction of its per-call cost)."""
    ux, uy, uz = u[:, 0], u[:, 1], u[:, 2]
    vx, vy, vz = v[:, 0], v[:, 1], v[:, 2]
    return np.stack((uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx), axis=1)


def fit_capsule(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Enclosing capsule (a, b, radius) of a point cloud along its principal axis."""
    centre = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - centre, full_matrices=False)
    axis = vt[0]
    t = (points - centre) @ axis
    perp = np.linalg.norm((points - centre) - t[:, None] * axis, axis=1)
    radius = float(perp.max())
    half = np.sqrt(np.maximum(radius**2 - perp**2, 0.0))
    # every point must lie within r of the segment: lowest end ≤ t_i + half_i, highest end ≥ t_i − half_i
    t_lo, t_hi = float(np.min(t + half)), float(np.max(t - half))
    if t_lo > t_hi:  # short, fat cloud: a sphere
        mid = 0.5 * (t_lo + t_hi)
        a = b = centre + mid * axis
        radius = float(np.linalg.norm(points - a, axis=1).max())
        return a, b.copy(), radius
    return centre + t_lo * axis, centre + t_hi * axis, radius


@dataclass
class Capsule:
    name: str
    group: int  # index into the UpperBodySpec's capsule groups
    frame_id: int  # pinocchio frame it rides on
    a: np.ndarray  # (3,) segment ends in that frame
    b: np.ndarray
    radius: float


def _rotation_z_to(v: np.ndarray) -> np.ndarray:
    """A rotation taking the z axis onto the unit vector ``v``."""
    z = np.array([0.0, 0.0, 1.0])
    c = np.cross(z, v)
    s, d = float(np.linalg.norm(c)), float(z @ v)
    if s < 1e-12:
        return np.eye(3) if d > 0 else np.diag([1.0, -1.0, -1.0])
    return pin.exp3(c / s * np.arctan2(s, d))


# ----------------------------------------------------------------------------- the capsule model


class CapsuleModel:
    """Capsules of one robot's upper body, the pairs to check, signed distances and the pose fixer."""

    def __init__(self, upper_body: UpperBody, seed: int = 0, pair_samples: int = 400):
        self.ub = upper_body
        self.capsules = _fit_groups(upper_body)
        self._frames = [c.frame_id for c in self.capsules]
        self._a = np.array([c.a for c in self.capsules])
        self._b = np.array([c.b for c in self.capsules])
        self._r = np.array([c.radius for c in self.capsules])
        self._masks = np.array([upper_body.support_mask(c.frame_id) for c in self.capsules])  # (C, n) joints moving each
        self.pairs = self._select_pairs(np.random.default_rng(seed), pair_samples)
        self._ia = np.array([i for i, _ in self.pairs], dtype=int)
        self._ib = np.array([j for _, j in self.pairs], dtype=int)
        self._geom_model, self._geom_data = self._coal_geometry()
        # references into the geometry data's result vector (updated in place by every computeDistances; its size
        # never changes): reading a distance through them skips the copy of a whole DistanceResult per pair
        self._results = list(self._geom_data.distanceResults)

    def _coal_geometry(self) -> tuple[pin.GeometryModel, pin.GeometryData]:
        """The capsules as coal capsules (axis = local z, centred) on their frames' joints, with our pairs."""
        pm = self.ub.pin_model
        gm = pin.GeometryModel()
        for c in self.capsules:
            frame = pm.frames[c.frame_id]
            axis = c.b - c.a
            length = float(np.linalg.norm(axis))
            rot = _rotation_z_to(axis / length) if length > 1e-9 else np.eye(3)
            placement = frame.placement * pin.SE3(rot, 0.5 * (c.a + c.b))
            gm.addGeometryObject(pin.GeometryObject(c.name, frame.parentJoint, c.frame_id, placement,
                                                    coal.Capsule(c.radius, length)))
        for i, j in self.pairs:
            gm.addCollisionPair(pin.CollisionPair(int(i), int(j)))
        return gm, pin.GeometryData(gm)

    def _distances(self, x: np.ndarray) -> int:
        """Forward kinematics of ``x`` (into ``ub.data``) and every pair's signed distance (into the geometry
        data); returns the index of the closest pair."""
        pin.framesForwardKinematics(self.ub.pin_model, self.ub.data, self.ub.full_q(x))
        pin.updateGeometryPlacements(self.ub.pin_model, self.ub.data, self._geom_model, self._geom_data)
        return int(pin.computeDistances(self._geom_model, self._geom_data))

    def min_signed_distance(self, x: np.ndarray) -> float:
        """The smallest signed distance over the checked pairs (m; negative = colliding)."""
        return float(self._results[self._distances(x)].min_distance)

    # --- geometry in the world (pelvis) frame
    def segments(self, x: np.ndarray, forward: bool = True) -> tuple[np.ndarray, np.ndarray]:
        d = self.ub.forward(x) if forward else self.ub.data
        h = np.array([d.oMf[f].homogeneous for f in self._frames])  # (C, 4, 4)
        a = np.einsum("cij,cj->ci", h[:, :3, :3], self._a) + h[:, :3, 3]
        b = np.einsum("cij,cj->ci", h[:, :3, :3], self._b) + h[:, :3, 3]
        return a, b

    @property
    def radii(self) -> np.ndarray:
        return np.array([c.radius for c in self.capsules])

    def capsule_min_distances(self, pair_distances: np.ndarray) -> np.ndarray:
        """(C,) each capsule's smallest signed distance over the checked pairs it is in (m; +inf for a capsule
        in no checked pair), from :meth:`signed_distances`' (P,) answer."""
        out = np.full(len(self.capsules), np.inf)
        d = np.asarray(pair_distances, dtype=float)
        np.minimum.at(out, self._ia, d)
        np.minimum.at(out, self._ib, d)
        return out

    def on_bodies(self) -> list["CapsuleOnBody"]:
        """The capsules placed on the MuJoCo bodies they ride on (what the studio draws)."""
        return capsules_on_bodies(self.ub, self.capsules)

    def signed_distances(self, x: np.ndarray) -> np.ndarray:
        """(P,) signed distance of every checked pair (m; negative = colliding)."""
        self._distances(x)
        return np.fromiter(map(_MIN_DISTANCE, self._results), float, len(self._results))

    def signed_distances_numpy(self, x: np.ndarray) -> np.ndarray:
        """:meth:`signed_distances` by the numpy segment test (the reference the coal path is checked against)."""
        a, b = self.segments(x)
        dist, _, _ = segment_distance(a[self._ia], b[self._ia], a[self._ib], b[self._ib])
        return dist - self._r[self._ia] - self._r[self._ib]

    def is_free(self, x: np.ndarray, margin_m: float = 0.0) -> bool:
        return self.min_signed_distance(x) >= margin_m

    def penetration(self, x: np.ndarray, clearance_m: float = 0.0) -> float:
        """Sum over pairs of how far each signed distance is below ``clearance_m`` (m, ≥ 0; 0: penetration)."""
        return float(np.sum(np.maximum(clearance_m - self.signed_distances(x), 0.0)))

    def colliding_pairs(self, x: np.ndarray) -> list[tuple[str, str, float]]:
        d = self.signed_distances(x)
        return [(self.capsules[i].name, self.capsules[j].name, float(d[k])) for k, (i, j) in enumerate(self.pairs) if d[k] < 0]

    def signed_distances_batch(self, xs: np.ndarray) -> np.ndarray:
        """(B, P) signed distances of B poses in one vectorised segment test (forward kinematics per pose)."""
        pm, d = self.ub.pin_model, self.ub.data
        import pinocchio as pin

        h = np.empty((len(xs), len(self._frames), 4, 4))
        for k, x in enumerate(xs):
            pin.framesForwardKinematics(pm, d, self.ub.full_q(x))
            h[k] = [d.oMf[f].homogeneous for f in self._frames]
        a = np.einsum("bcij,cj->bci", h[:, :, :3, :3], self._a) + h[:, :, :3, 3]
        b = np.einsum("bcij,cj->bci", h[:, :, :3, :3], self._b) + h[:, :, :3, 3]
        dist, _, _ = segment_distance(a[:, self._ia], b[:, self._ia], a[:, self._ib], b[:, self._ib])
        return dist - self._r[self._ia] - self._r[self._ib]

    def interpolation_free(self, x0: np.ndarray, x1: np.ndarray, step_rad: float = 0.1, end_free: bool = False) -> bool:
        """Linear interpolation x0 → x1 collision-free at every ``step_rad`` of the largest joint change.
        ``end_free``: x1 is known to be collision-free (checked by the caller), so only the poses between are."""
        n = max(1, int(np.ceil(np.max(np.abs(x1 - x0)) / step_rad)))
        for k in range(n - 1 if end_free else n, 0, -1):  # the end first: a colliding target fails on the first check
            if self.min_signed_distance(x0 + (k / n) * (x1 - x0)) < 0.0:
                return False
        return True

    # --- the fixer (§III)
    def fix(self, x: np.ndarray, margin_m: float = 0.002, max_iters: int = 60, damping: float = 1e-3,
            clearance_m: float = 0.0) -> tuple[np.ndarray, bool]:
        """Push colliding capsules apart until every signed distance ≥ ``clearance_m`` (default 0: collision-
        free). Returns (x, success).

        Each iteration moves the closest points of every pair closer than ``clearance_m + margin_m`` apart by
        the missing distance, through the stacked point Jacobians (damped least squares), clipped to the joint
        limits; a step is halved until the total penetration (below the clearance) does not increase (it never
        does)."""
        x = self.ub.clip(np.asarray(x, dtype=float).copy())
        # one C++ check gives every pair's distance (the free case returns here); they are then carried from each
        # accepted step (no re-evaluation)
        d_all = self.signed_distances(x)
        if d_all.min() >= clearance_m:
            return x, True
        target = clearance_m + margin_m
        pen = float(np.sum(np.maximum(clearance_m - d_all, 0.0)))
        for _ in range(max_iters):
            if pen == 0.0 and np.all(d_all >= clearance_m):
                return x, True
            self.ub.jacobians(x)
            active = np.nonzero(d_all < target)[0]
            ia, ib = self._ia[active], self._ib[active]
            # closest points of the capsule axes from coal's answer for x (still in the geometry data: d_all was
            # its last computeDistances): surface points p1 = c1 + r1·normal, p2 = c2 − r2·normal, normal = c2 − c1
            # normalised (equal to the numpy segment test to 1e-13, tested)
            near = [self._results[k] for k in active]
            normal = np.array([r.normal for r in near])
            c1 = np.array([r.getNearestPoint1() for r in near]) - self._r[ia, None] * normal
            c2 = np.array([r.getNearestPoint2() for r in near]) + self._r[ib, None] * normal
            n = -normal
            norm = np.ones(len(active))
            crossing = d_all[active] + self._r[ia] + self._r[ib] < 1e-9
            if crossing.any():  # segments cross: push along the line between capsule centres
                a, b = self.segments(x, forward=False)
                centres = 0.5 * (a[ia] + b[ia] - a[ib] - b[ib])
                n = np.where(crossing[:, None], centres, n)
                norm = np.where(crossing, np.linalg.norm(centres, axis=1) + 1e-12, norm)
            n = n / norm[:, None]
            # row = n · (J(c1) − J(c2)); a point c on a capsule moves by mask ⊙ (linear + angular × c), and
            # n · (angular × c) = angular · (c × n): all rows from the world joint Jacobian in a few products
            lin, ang = self.ub.driven_jacobian()
            nl = n @ lin
            jac = (self._masks[ia] * (nl + _cross(c1, n) @ ang)) - (self._masks[ib] * (nl + _cross(c2, n) @ ang))
            rhs = target - d_all[active]
            dx = jac.T @ np.linalg.solve(jac @ jac.T + damping * np.eye(len(active)), rhs)
            step, accepted = 1.0, False
            while step > 1e-3:
                x_new = self.ub.clip(x + step * dx)
                d_new = self.signed_distances(x_new)
                pen_new = float(np.sum(np.maximum(clearance_m - d_new, 0.0)))
                if pen_new <= pen:
                    x, pen, d_all, accepted = x_new, pen_new, d_new, True
                    break
                step *= 0.5
            if not accepted:
                break
        return x, bool(np.min(d_all) >= clearance_m)

    # --- pair selection
    def _select_pairs(self, rng: np.random.Generator, n_samples: int) -> list[tuple[int, int]]:
        pm = self.ub.pin_model
        caps = self.capsules
        joint_of = [pm.frames[c.frame_id].parentJoint for c in caps]
        candidates = []
        for i in range(len(caps)):
            for j in range(i + 1, len(caps)):
                ji, jj = joint_of[i], joint_of[j]
                if caps[i].group == caps[j].group or ji == jj or pm.parents[ji] == jj or pm.parents[jj] == ji:
                    continue  # same or neighbouring links
                if not (_moves_between(pm, ji, jj, self.ub.q_index)):
                    continue  # rigidly fixed relative to each other under the driven joints
                candidates.append((i, j))
        ia = np.array([i for i, _ in candidates])
        ib = np.array([j for _, j in candidates])
        r = np.array([c.radius for c in caps])
        touching = np.zeros(len(candidates))
        for _ in range(n_samples):
            x = rng.uniform(self.ub.lower, self.ub.upper)
            a, b = self.segments(x)
            dist, _, _ = segment_distance(a[ia], b[ia], a[ib], b[ib])
            touching += dist - r[ia] - r[ib] < 0
        return [p for p, t in zip(candidates, touching) if t < ALWAYS_TOUCHING_FRACTION * n_samples]


@dataclass(frozen=True)
class CapsuleOnBody:
    """A capsule as drawn on the robot: the MuJoCo body it rides on (the body named like its pinocchio frame),
    its centre and orientation (the capsule's axis is local z) in that body's frame, the distance between its
    two sphere centres and its radius (m)."""

    name: str
    body: str
    position: np.ndarray  # (3,)
    wxyz: np.ndarray  # (4,)
    length: float
    radius: float


def capsules_on_bodies(ub: UpperBody, capsules: list[Capsule]) -> list[CapsuleOnBody]:
    """``capsules`` (in their pinocchio frames) in the frames of the MuJoCo bodies of the same name, so a body
    pose streamed from the simulation places them: body ∘ placement = the capsule in the world. The frame-to-body
    transform is measured once in the fitting pose (pinocchio and MuJoCo kinematics of the same configuration; a
    frame and the body of its name are one link, so it holds in every pose — tested on random poses); ValueError
    when a capsule's frame is no MuJoCo body."""
    mm = ub.model.mj_model
    data = mujoco.MjData(mm)
    q = ub.full_q(np.zeros(ub.n))
    data.qpos[:] = ub.model.mj_qpos_from_pin(q)
    mujoco.mj_kinematics(mm, data)
    pdata = ub.forward(np.zeros(ub.n))
    out = []
    for c in capsules:
        frame = ub.pin_model.frames[c.frame_id]
        bid = mujoco.mj_name2id(mm, mujoco.mjtObj.mjOBJ_BODY, frame.name)
        if bid < 0:
            raise ValueError(f"capsule {c.name}: frame {frame.name!r} is no body of the {ub.model.name} MuJoCo model")
        body_rot = data.xmat[bid].reshape(3, 3)
        f = pdata.oMf[c.frame_id]
        rot_fb = body_rot.T @ f.rotation  # the pinocchio frame in the body's frame
        pos_fb = body_rot.T @ (f.translation - data.xpos[bid])
        axis = c.b - c.a
        length = float(np.linalg.norm(axis))
        rot_c = _rotation_z_to(axis / length) if length > 1e-9 else np.eye(3)
        xyzw = pin.Quaternion(rot_fb @ rot_c).coeffs()
        out.append(CapsuleOnBody(c.name, frame.name, rot_fb @ (0.5 * (c.a + c.b)) + pos_fb,
                                 np.array([xyzw[3], xyzw[0], xyzw[1], xyzw[2]]), length, float(c.radius)))
    return out


def fitted_capsules_on_bodies(robot: str) -> list[CapsuleOnBody]:
    """The capsules LWL2 checks for ``robot`` (the same deterministic fit as :class:`CapsuleModel`'s, without its
    pair selection), placed on their MuJoCo bodies — cheap enough for the studio (≈ 10 ms once the robot loaded)."""
    ub = UpperBody(robot)
    return capsules_on_bodies(ub, _fit_groups(ub))


def _moves_between(pm, ja: int, jb: int, q_index: np.ndarray) -> bool:
    """Is there a driven joint on the kinematic path between joints ja and jb?"""
    def chain(j):
        out = []
        while j > 0:
            out.append(j)
            j = pm.parents[j]
        return out

    ca, cb = chain(ja), chain(jb)
    common = set(ca) & set(cb)
    path = [j for j in ca + cb if j not in common]
    driven = {int(pm.joints[j].idx_q) for j in path}
    return bool(driven & set(int(i) for i in q_index))


def _geom_local_points(mm: mujoco.MjModel, gid: int) -> np.ndarray | None:
    """Points whose convex hull is the collision geom (mesh vertices, box corners, cylinder/capsule rims)."""
    kind, size = int(mm.geom_type[gid]), mm.geom_size[gid]
    g = mujoco.mjtGeom
    if kind == int(g.mjGEOM_MESH):
        mid = int(mm.geom_dataid[gid])
        return mm.mesh_vert[mm.mesh_vertadr[mid]: mm.mesh_vertadr[mid] + mm.mesh_vertnum[mid]].astype(float)
    if kind == int(g.mjGEOM_BOX):
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * size
    if kind in (int(g.mjGEOM_CYLINDER), int(g.mjGEOM_CAPSULE)):
        ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
        ring = np.stack([size[0] * np.cos(ang), size[0] * np.sin(ang)], axis=1)
        # a rim polygon's circumscribed circle: scale so the polygon contains the circle
        ring /= np.cos(np.pi / 24)
        ext = size[1] + (size[0] if kind == int(g.mjGEOM_CAPSULE) else 0.0)
        return np.concatenate([np.column_stack([ring, np.full(24, z)]) for z in (-ext, ext)])
    if kind == int(g.mjGEOM_SPHERE):
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * size[0]
    return None


def _fit_groups(ub: UpperBody) -> list[Capsule]:
    """Fit one capsule per group to the MuJoCo collision meshes (group 3), in the group's pinocchio frame."""
    mm = ub.model.mj_model
    data = mujoco.MjData(mm)
    data.qpos[:] = ub.model.mj_qpos_from_pin(ub.full_q(np.zeros(ub.n)))
    mujoco.mj_kinematics(mm, data)
    pdata = ub.forward(np.zeros(ub.n))
    caps = []
    for gi, group in enumerate(ub.spec.capsules):
        pts = []
        for body in group.bodies:
            bid = mujoco.mj_name2id(mm, mujoco.mjtObj.mjOBJ_BODY, body)
            if bid < 0:
                raise ValueError(f"capsule {group.name}: body {body!r} not in the {ub.model.name} model")
            for gid in np.nonzero(mm.geom_bodyid == bid)[0]:
                if mm.geom_group[gid] != 3:
                    continue
                v = _geom_local_points(mm, int(gid))
                if v is not None:
                    pts.append(v @ data.geom_xmat[gid].reshape(3, 3).T + data.geom_xpos[gid])
        if not pts:
            raise ValueError(f"capsule {group.name}: no collision mesh on {group.bodies}")
        world = np.concatenate(pts)
        fid = ub.pin_model.getFrameId(group.frame)
        m = pdata.oMf[fid]
        local = (world - m.translation) @ m.rotation  # R^T (p - t)
        a, b, r = fit_capsule(local)
        caps.append(Capsule(group.name, gi, fid, a, b, r))
    return caps


# ----------------------------------------------------------------------------- MuJoCo agreement


def mujoco_agreement(cm: CapsuleModel, n_poses: int = 500, seed: int = 1) -> dict:
    """Random poses within the limits: do the capsules flag a collision whenever MuJoCo's own collision
    detection (the collision hulls) finds one between two checked groups? Conservative = no missed pose."""
    ub = cm.ub
    mm = ub.model.mj_model
    data = mujoco.MjData(mm)
    body_group = {}
    for gi, group in enumerate(ub.spec.capsules):
        for body in group.bodies:
            body_group[mujoco.mj_name2id(mm, mujoco.mjtObj.mjOBJ_BODY, body)] = gi
    checked = {frozenset((cm.capsules[i].group, cm.capsules[j].group)) for i, j in cm.pairs}
    rng = np.random.default_rng(seed)
    both = caps_only = mj_only = neither = 0
    for _ in range(n_poses):
        x = rng.uniform(ub.lower, ub.upper)
        data.qpos[:] = ub.model.mj_qpos_from_pin(ub.full_q(x))
        data.qpos[2] += 5.0
        mujoco.mj_forward(mm, data)
        mj_hit = False
        for c in data.contact[: data.ncon]:
            g1 = body_group.get(int(mm.geom_bodyid[c.geom1]))
            g2 = body_group.get(int(mm.geom_bodyid[c.geom2]))
            if g1 is not None and g2 is not None and frozenset((g1, g2)) in checked and c.dist < 0:
                mj_hit = True
                break
        cap_hit = not cm.is_free(x)
        both += mj_hit and cap_hit
        caps_only += cap_hit and not mj_hit
        mj_only += mj_hit and not cap_hit
        neither += not (mj_hit or cap_hit)
    return {"poses": n_poses, "both_collide": both, "capsules_only": caps_only, "mujoco_only": mj_only,
            "neither": neither, "agreement": round((both + neither) / n_poses, 3),
            "conservative": mj_only == 0}


__all__ = ["segment_distance", "fit_capsule", "Capsule", "CapsuleModel", "CapsuleOnBody", "capsules_on_bodies",
           "fitted_capsules_on_bodies", "mujoco_agreement"]
