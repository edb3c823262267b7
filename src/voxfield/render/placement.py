"""Is a camera somewhere a viewer could stand, looking at something? A view from inside a
voxel, or from under a terrain's surface (a hollow terrain leaves empty space below its
shell, so the eye is not inside any voxel there), or one that looks away from the scene
altogether, makes every number measured from it meaningless."""

from __future__ import annotations

import dataclasses

import numpy as np

from voxfield.error_table.directions import fibonacci_directions
from voxfield.errors import VoxfieldError
from voxfield.kernels.camera_rays import ORTHOGRAPHIC, PINHOLE
from voxfield.kernels.colour import decode_channel
from voxfield.render.camera import Camera
from voxfield.render.ray_query import trace
from voxfield.svo.octree import Octree

#: Rays cast from the eye over the whole sphere.
PROBE_RAYS = 256
#: Under geometry: at least this share of the upper hemisphere is blocked while at least
#: this share of the lower one escapes (an upside-down world: sky covered, ground open).
COVERED_SKY = 0.75
OPEN_GROUND = 0.5


#: The empty-view test's rays: a grid of at most this many a side over the image.
VIEW_SAMPLES = 256


def empty_view_problem(octree: Octree, camera: Camera) -> str | None:
    """That ``camera`` sees nothing of the scene (one sentence), or None: no ray of the view
    (a grid of at most ``VIEW_SAMPLES``² over the image, its border included) meets the
    scene's voxel box. NumPy only, no kernel to compile. Probe cameras see every way."""
    if camera.kind not in (PINHOLE, ORTHOGRAPHIC):
        return None
    sampled = dataclasses.replace(camera, width=min(camera.width, VIEW_SAMPLES),
                                  height=min(camera.height, VIEW_SAMPLES))
    origins, dirs = sampled.rays()
    lo, hi = (np.asarray(b, np.float64) for b in octree.voxel_bounds)
    with np.errstate(divide="ignore", invalid="ignore"):
        near = (lo - origins) / dirs
        far = (hi - origins) / dirs
    # fmin/fmax pass over the NaN of a ray in a slab's plane (0/0): that slab does not bound it.
    enter = np.fmax.reduce(np.fmin(near, far), axis=1)
    leave = np.fmin.reduce(np.fmax(near, far), axis=1)
    if np.any(leave >= np.maximum(enter, 0.0)):
        return None
    where = ", ".join(f"{v:.1f}" for v in camera.position)
    return (f"the view from ({where}) meets nothing of the scene (its box "
            f"{tuple(int(v) for v in lo)}..{tuple(int(v) for v in hi)}): every image of it "
            "is empty")


def camera_placement_problem(octree: Octree, camera: Camera) -> str | None:
    """Why ``camera`` stands where no viewer could, or sees nothing (one sentence), or
    None. Only pinhole cameras are checked for their eye: orthographic and probe cameras
    have no single one."""
    empty = empty_view_problem(octree, camera)
    if empty is not None:
        return empty
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


#: The one-colour test's rays: a grid of at most this many a side over the image.
COLOUR_SAMPLES = 64


def one_colour_view_note(octree: Octree, camera: Camera, channel: str = "albedo") -> str | None:
    """That every voxel ``camera`` sees has one colour in ``channel`` (one sentence), or
    None. Every LOD of such a view averages that colour, so the renderers a study compares
    differ in outlines alone (PSNR ∞ where those match too): the top view of a one-colour roof,
    any view of a one-colour model. A grid of at most ``COLOUR_SAMPLES``² rays decides."""
    if camera.kind not in (PINHOLE, ORTHOGRAPHIC):
        return None
    stored = octree.channel(channel)
    sampled = dataclasses.replace(camera, width=min(camera.width, COLOUR_SAMPLES),
                                  height=min(camera.height, COLOUR_SAMPLES))
    origins, dirs = sampled.rays()
    hits = trace(octree, origins, dirs, lod=0)
    seen = stored[hits.node[hits.hit]]
    if len(seen) == 0 or np.any(seen != seen[0]):
        return None
    rgb = ", ".join(f"{v:.3g}" for v in decode_channel(seen[:1])[0])
    return (f"every voxel the view sees has one colour in {channel!r} (linear RGB {rgb}), so "
            "the renderers measured differ in outlines alone; a view of more of the scene "
            "(--camera, --eye/--target) or another --channel measures more")


def could_be_buried(octree: Octree, camera: Camera) -> bool:
    """Whether a pinhole eye stands over the scene's footprint and below its top, the only
    places it can be inside a voxel or under a surface (an eye outside that column of space
    is neither)."""
    if camera.kind != PINHOLE:
        return False
    lo, hi = (np.asarray(b, np.float64) for b in octree.voxel_bounds)
    x, y, z = np.asarray(camera.position, np.float64)
    return bool(lo[0] <= x <= hi[0] and lo[2] <= z <= hi[2] and y <= hi[1])


def view_note(octree: Octree, camera: Camera) -> str | None:
    """What a render should say about where its camera stands (``camera_placement_problem``),
    with the eye's rays cast only where ``could_be_buried``: a render from outside the
    scene, the usual case, compiles no ray query for it."""
    if could_be_buried(octree, camera):
        return camera_placement_problem(octree, camera)
    return empty_view_problem(octree, camera)


def check_camera_placement(octree: Octree, camera: Camera) -> None:
    """Refuse a camera that stands inside or under geometry, with the reason."""
    problem = camera_placement_problem(octree, camera)
    if problem is not None:
        raise VoxfieldError(f"{problem}; place it with --eye/--target or another --camera")
