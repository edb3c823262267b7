"""Is a camera somewhere a viewer could stand? A view from inside a voxel, or from under a
terrain's surface (a hollow terrain leaves empty space below its shell, so the eye is not
inside any voxel there), makes every number measured from it meaningless."""

from __future__ import annotations

import numpy as np

from voxfield.error_table.directions import fibonacci_directions
from voxfield.errors import VoxfieldError
from voxfield.kernels.camera_rays import PINHOLE
from voxfield.render.camera import Camera
from voxfield.render.ray_query import trace
from voxfield.svo.octree import Octree

#: Rays cast from the eye over the whole sphere.
PROBE_RAYS = 256
#: Under geometry: at least this share of the upper hemisphere is blocked while at least
#: this share of the lower one escapes (an upside-down world: sky covered, ground open).
COVERED_SKY = 0.75
OPEN_GROUND = 0.5


def camera_placement_problem(octree: Octree, camera: Camera) -> str | None:
    """Why ``camera`` stands where no viewer could (one sentence), or None. Only pinhole
    cameras are checked: orthographic and probe cameras have no single eye."""
    if camera.kind != PINHOLE:
        return None
    eye = np.asarray(camera.position, np.float64)
    dirs = fibonacci_directions(PROBE_RAYS)
    hits = trace(octree, np.repeat(eye[None], len(dirs), axis=0), dirs, lod=0)
    where = ", ".join(f"{v:.1f}" for v in eye)
    if np.all(hits.hit & (hits.t <= 0.0)):
        return f"the camera at ({where}) is inside a voxel"
    up = dirs[:, 1] > 0.2
    down = dirs[:, 1] < -0.2
    covered = float(np.mean(hits.hit[up]))
    open_below = float(np.mean(~hits.hit[down]))
    if covered >= COVERED_SKY and open_below >= OPEN_GROUND:
        return (f"the camera at ({where}) is under the scene's surface: {100 * covered:.0f} % "
                f"of the sky above it is blocked while {100 * open_below:.0f} % of the rays "
                "below it escape")
    return None


def check_camera_placement(octree: Octree, camera: Camera) -> None:
    """Refuse a camera that stands inside or under geometry, with the reason."""
    problem = camera_placement_problem(octree, camera)
    if problem is not None:
        raise VoxfieldError(f"{problem}; place it with --eye/--target or another --camera")
