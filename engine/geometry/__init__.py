"""Geometry of the engine: rotations (one convention: matrices world ← body, quaternions w, x, y, z),
planar convex polygons, smooth scalar blends. Import from the submodules or from here."""

from engine.geometry.polygon import (  # noqa: F401
    clip_convex_polygons,
    clip_into_polygon,
    convex_hull,
    convex_hull_2d,
    point_in_polygon,
    polygon_area,
    polygon_centroid,
    polygon_halfplanes,
)
from engine.geometry.rotation import (  # noqa: F401
    exp_so3,
    log_so3,
    matrix_from_quat,
    quat_from_matrix,
    rot_x,
    rot_y,
    rot_z,
    rot_zyx,
    slerp_matrix,
    wrap_angle,
    yaw_of,
)
from engine.geometry.smooth import smooth_max, smooth_min, smoothstep, smoothstep_rate  # noqa: F401
from engine.geometry.vector import vector_norm  # noqa: F401
