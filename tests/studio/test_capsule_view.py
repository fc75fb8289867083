"""The capsules drawn on the robot: a closed, outward-wound mesh; tints sent only for capsules that changed."""

from __future__ import annotations

import numpy as np
import viser

from studio.capsule_view import COLLIDING, COLORS, FREE, NEAR, CapsuleView, capsule_mesh, tint_states
from tests.conftest import free_port


def test_the_capsule_mesh_is_closed_outward_and_the_right_size():
    verts, faces = capsule_mesh(0.3, 0.05)
    v = verts.astype(float)
    # every edge is shared by exactly two faces in opposite directions: closed and consistently wound
    edges: dict[tuple[int, int], int] = {}
    for f in faces:
        for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])):
            edges[(int(a), int(b))] = edges.get((int(a), int(b)), 0) + 1
    assert all(n == 1 and edges.get((b, a)) == 1 for (a, b), n in edges.items())
    normals = np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])
    assert np.all(np.einsum("ij,ij->i", normals, v[faces].mean(axis=1)) > 0)  # outward (convex, about the origin)
    assert np.isclose(v[:, 2].max(), 0.2) and np.isclose(v[:, 2].min(), -0.2)
    assert np.max(np.linalg.norm(v[:, :2], axis=1)) <= 0.05 + 1e-7


def test_tints_follow_the_distances_and_only_changes_are_sent():
    from engine.retarget.humanoid_arm.capsules import fitted_capsules_on_bodies

    assert list(tint_states(np.array([-0.001, 0.0, 0.019, 0.02, np.inf]))) == [COLLIDING, NEAR, NEAR, FREE, FREE]
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        caps = fitted_capsules_on_bodies("g1")
        view = CapsuleView(server)
        with server.atomic():
            for body in {c.body for c in caps}:
                server.scene.add_frame(f"/robot/{body}", show_axes=False)
        view.build(caps, visible=True)
        assert len(view.meshes) == len(caps) == 13
        assert all(m.name == f"/robot/{c.body}/capsule_{c.name}" for m, c in zip(view.meshes, caps))
        d = np.full(len(caps), 0.1)
        assert view.tint(d) == 0 and view.tints_sent == 0
        d[[2, 5]] = -0.01, 0.01
        assert view.tint(d) == 2 and view.tints_sent == 2
        assert tuple(view.meshes[2].color) == COLORS[COLLIDING] and tuple(view.meshes[5].color) == COLORS[NEAR]
        assert view.tint(d) == 0  # unchanged: nothing sent
        assert view.tint(np.zeros(4)) == 0  # another robot's distances: ignored
        assert view.tint(None) == 2 and tuple(view.meshes[2].color) == COLORS[FREE]
        view.set_visible(False)
        assert not any(m.visible for m in view.meshes)
        view.clear()
        assert not view.meshes
    finally:
        server.stop()
