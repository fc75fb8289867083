"""Mesh conversion for the robot library: DAE/STL/OBJ in, STL out, cached by content hash.

MuJoCo reads only STL/OBJ and the browser wants light meshes, so every mesh a URDF names is
converted once into the cache: visual meshes decimated to a face budget, collision meshes
reduced to a simplified convex hull (what MuJoCo collides with anyway).
"""

from __future__ import annotations

import hashlib
import os
import re
from pathlib import Path

from typing import TYPE_CHECKING

import numpy as np

from engine.atomic_io import atomic_write_bytes

if TYPE_CHECKING:
    import trimesh

CACHE_VERSION = "4"


def cache_root() -> Path:
    """Cache folder; ``MOTION_STUDIO_CACHE`` overrides ``$XDG_CACHE_HOME/motion-studio``."""
    env = os.environ.get("MOTION_STUDIO_CACHE")
    if env:
        return Path(env)
    base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
    return base / "motion-studio"


def file_digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _declared_dae_up_axis(path: Path) -> str:
    head = path.read_bytes()[:20000].decode("utf-8", "ignore")
    match = re.search(r"<up_axis>\s*([XYZ]_UP)\s*</up_axis>", head)
    return match.group(1) if match else "Y_UP"  # COLLADA's default


def load_mesh(path: Path, dae_up_axis: str | None = None) -> "trimesh.Trimesh":
    """Load any mesh file as one triangle mesh in the URDF's (z-up) convention.

    For COLLADA, ``dae_up_axis`` overrides the axis the file declares (some packaged files
    declare Y_UP while their geometry is z-up, which ROS tools silently ignore).
    """
    import trimesh

    mesh = trimesh.load(str(path), force="mesh", process=False)
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError(f"{path.name}: no triangles")
    if path.suffix.lower() == ".dae":
        up = dae_up_axis or _declared_dae_up_axis(path)
        if up == "Y_UP":
            mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    mesh.merge_vertices()
    return mesh


def _cluster_vertices(mesh: "trimesh.Trimesh", cell_m: float) -> "trimesh.Trimesh":
    """Vertex clustering on a grid: robust (if coarse) reduction for non-manifold meshes."""
    import trimesh

    keys = np.floor(mesh.vertices / cell_m).astype(np.int64)
    _, inverse = np.unique(keys, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    n = int(inverse.max()) + 1
    sums = np.zeros((n, 3))
    np.add.at(sums, inverse, mesh.vertices)
    counts = np.bincount(inverse, minlength=n)[:, None]
    faces = inverse[mesh.faces]
    keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    faces = np.unique(np.sort(faces[keep], axis=1), axis=0, return_index=True)[1]
    faces = inverse[mesh.faces][keep][np.sort(faces)]
    return trimesh.Trimesh(vertices=sums / counts, faces=faces, process=True)


def decimate(mesh: "trimesh.Trimesh", target_faces: int) -> "trimesh.Trimesh":
    """Reduce to about ``target_faces`` (quadric decimation, then clustering where it stalls)."""
    target_faces = max(int(target_faces), 12)
    if len(mesh.faces) <= target_faces:
        return mesh
    import fast_simplification
    import trimesh

    verts, faces = fast_simplification.simplify(
        np.asarray(mesh.vertices, dtype=np.float32), np.asarray(mesh.faces, dtype=np.int64),
        target_count=target_faces,
    )
    out = trimesh.Trimesh(vertices=verts, faces=faces, process=True)
    if len(out.faces) == 0:
        out = mesh
    cell = float(np.linalg.norm(mesh.extents)) / 400.0
    while len(out.faces) > 1.5 * target_faces and cell < float(np.linalg.norm(mesh.extents)) / 8:
        clustered = _cluster_vertices(out, cell)
        if len(clustered.faces) > 0:
            out = clustered
        cell *= 1.5
    return out


def convex_collision(mesh: "trimesh.Trimesh", target_faces: int) -> "trimesh.Trimesh":
    hull = mesh.convex_hull
    if len(hull.faces) > target_faces:
        hull = decimate(hull, target_faces).convex_hull
    return hull


def convert(src: Path, role: str, target_faces: int, dae_up_axis: str | None, cache_dir: Path) -> Path:
    """Convert ``src`` for ``role`` ("visual" or "collision"); return the cached STL path."""
    key = hashlib.sha256(
        f"{CACHE_VERSION}|{file_digest(src)}|{role}|{target_faces}|{dae_up_axis}|{src.suffix.lower()}".encode()
    ).hexdigest()[:20]
    out = cache_dir / "meshes" / f"{src.stem}-{role}-{key}.stl"
    if out.is_file():
        return out
    mesh = load_mesh(src, dae_up_axis)
    mesh = convex_collision(mesh, target_faces) if role == "collision" else decimate(mesh, target_faces)
    data = mesh.export(file_type="stl")
    atomic_write_bytes(out, data if isinstance(data, bytes) else str(data).encode())
    return out


def face_count(path: Path) -> int:
    """Cheap face count: exact for binary STL, a load otherwise."""
    if path.suffix.lower() == ".stl":
        with open(path, "rb") as f:
            header = f.read(84)
        if len(header) == 84:
            n = int.from_bytes(header[80:84], "little")
            if 84 + 50 * n == path.stat().st_size:
                return n
    import trimesh

    try:
        mesh = trimesh.load(str(path), force="mesh", process=False)
        return len(getattr(mesh, "faces", ()))
    except Exception:
        return 1000
