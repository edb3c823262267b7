"""Cameras: pinhole (look-at), orthographic, and the six 90° cube-map faces of a probe."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from voxfield.checks import integer_in, is_real, seed_value
from voxfield.errors import CameraError, VoxfieldError
from voxfield.kernels.camera_rays import OCTAHEDRAL, ORTHOGRAPHIC, PINHOLE, camera_ray_arrays

#: Cube-map faces in the OpenGL/DirectX order and orientation: (name, forward, up).
CUBE_FACES = (
    ("+x", (1.0, 0.0, 0.0), (0.0, -1.0, 0.0)),
    ("-x", (-1.0, 0.0, 0.0), (0.0, -1.0, 0.0)),
    ("+y", (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    ("-y", (0.0, -1.0, 0.0), (0.0, 0.0, -1.0)),
    ("+z", (0.0, 0.0, 1.0), (0.0, -1.0, 0.0)),
    ("-z", (0.0, 0.0, -1.0), (0.0, -1.0, 0.0)),
)


def _vector(value, what: str) -> np.ndarray:
    try:
        v = np.asarray(value, dtype=np.float64).reshape(3)
    except (TypeError, ValueError) as exc:
        raise CameraError(f"camera {what} must be three numbers, got {value!r}") from exc
    if not np.isfinite(v).all():
        raise CameraError(f"camera {what} holds NaN or infinity: {v.tolist()}")
    return v


#: Narrowest field of view: the preset views stand back by the field's cotangent, and at
#: far narrower angles the eye is so far away that float64 positions on the map lose their
#: voxels (1e-300°, accepted before, drew an empty image).
MIN_FOV_DEG = 0.01


def _box(bounds_min, bounds_max) -> tuple[np.ndarray, np.ndarray]:
    """A scene box's corners, three finite numbers each, the minimum below the maximum."""
    lo = _vector(bounds_min, "box minimum")
    hi = _vector(bounds_max, "box maximum")
    if np.any(lo > hi):
        raise CameraError(f"the box's minimum {lo.tolist()} exceeds its maximum {hi.tolist()}")
    with np.errstate(over="ignore"):  # the presets frame it by its diagonal: checked here
        diagonal = float(np.linalg.norm(hi - lo))
    if not np.isfinite(diagonal):
        raise CameraError(f"the box {lo.tolist()}..{hi.tolist()} is too large to frame: its "
                          "diagonal overflows float64")
    return lo, hi


def _check_fov(fov_deg) -> None:
    if not is_real(fov_deg) or not (MIN_FOV_DEG <= float(fov_deg) < 180.0):
        raise CameraError(f"field of view must be at least {MIN_FOV_DEG} and below 180 "
                          f"degrees, got {fov_deg}")


#: Largest image side, for the library's cameras and the command line alike.
MAX_IMAGE_SIDE = 16384


def _image_size(width, height) -> tuple[int, int]:
    """Whole pixels in 1..MAX_IMAGE_SIDE (a 16.5-pixel image would silently become 16)."""
    height = width if height is None else height
    try:
        return (integer_in(width, "image width", 1, MAX_IMAGE_SIDE),
                integer_in(height, "image height", 1, MAX_IMAGE_SIDE))
    except VoxfieldError as exc:
        raise CameraError(str(exc)) from None


#: The world's up (y), and the up a camera looking straight down or up takes instead: -z,
#: as ``top_down_camera``'s, so such a view shows the map as the top view does.
WORLD_UP = (0.0, 1.0, 0.0)
VERTICAL_VIEW_UP = (0.0, 0.0, -1.0)


def unit_vectors(v: np.ndarray) -> np.ndarray:
    """``v / |v|`` along the last axis, each vector scaled to a largest component of 1
    first: the length of a finite vector cannot then overflow ((1e200, 1e200, 0) squares to
    infinity) nor underflow ((1e-200, 0, 0) squares to zero). Zero vectors are the
    caller's to refuse."""
    v = v / np.abs(v).max(axis=-1, keepdims=True)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _basis(forward, up=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orthonormal (forward, right, up) with right = forward × up (right-handed, y-up).
    ``up=None``: the world's up, or ``VERTICAL_VIEW_UP`` for a view along it."""
    f = _vector(forward, "direction")
    if not np.any(f):
        raise CameraError("camera direction is zero (eye and target coincide?)")
    f = unit_vectors(f)
    if up is None:
        up = VERTICAL_VIEW_UP if np.linalg.norm(np.cross(f, WORLD_UP)) < 1e-9 else WORLD_UP
    u = _vector(up, "up vector")
    r = np.cross(f, u)
    if np.linalg.norm(r) < 1e-9:
        raise CameraError("camera up vector is parallel to the view direction; pick another up")
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    return f, r, u


#: The octahedral camera's fixed frame (its kernels map directions, not this basis), made
#: once, read-only as every camera shares it: a probe bake makes a camera per probe.
_OCTAHEDRAL_BASIS = _basis((0.0, 0.0, -1.0), (0.0, 1.0, 0.0))
for _axis in _OCTAHEDRAL_BASIS:
    _axis.flags.writeable = False


@dataclass(frozen=True)
class Camera:
    """A camera producing one ray per image position; immutable, packed for kernels."""

    kind: int
    position: np.ndarray
    forward: np.ndarray
    right: np.ndarray
    up: np.ndarray
    half_width: float
    half_height: float
    width: int
    height: int

    def __post_init__(self) -> None:
        """The constructors make valid cameras; this catches one assembled field by field
        (or by ``dataclasses.replace``), whose packed parameters the kernels would misread."""
        _image_size(self.width, self.height)
        if self.kind not in (PINHOLE, ORTHOGRAPHIC, OCTAHEDRAL):
            raise CameraError(f"unknown camera kind {self.kind!r}")
        try:
            vectors = np.array([self.position, self.forward, self.right, self.up], np.float64)
        except (TypeError, ValueError):  # ragged, or not numbers
            vectors = None
        if vectors is None or vectors.shape != (4, 3) or not np.isfinite(vectors).all():
            raise CameraError("camera position, forward, right and up must be three finite "
                              "numbers each")
        basis = vectors[1:]
        if not np.abs(basis @ basis.T - np.eye(3)).max() <= 1e-9:
            raise CameraError("camera forward, right and up must be orthonormal")
        # Checked copies, read-only: ``camera.position[1] += 10`` would move a checked camera
        # past every check (a NaN there rendered a black image without a word).
        vectors.flags.writeable = False
        for name, row in zip(("position", "forward", "right", "up"), vectors, strict=True):
            object.__setattr__(self, name, row)
        for name in ("half_width", "half_height"):
            # A string or None failed inside NumPy's isfinite with its own TypeError.
            if not is_real(getattr(self, name)):
                raise CameraError(f"camera {name} must be a number, got "
                                  f"{getattr(self, name)!r}")
        if not (np.isfinite(self.half_width) and np.isfinite(self.half_height)):
            raise CameraError("camera field of view or extent is not finite")
        if self.half_width <= 0.0 or self.half_height <= 0.0:
            raise CameraError("camera field of view or extent must be positive")

    @classmethod
    def look_at(
        cls, eye, target, up=None, *, fov_deg: float = 60.0,
        width: int = 512, height: int | None = None,
    ) -> Camera:
        """Pinhole camera; ``fov_deg`` is the vertical field of view. ``up`` defaults to the
        world's, or to ``VERTICAL_VIEW_UP`` for a view straight down or up."""
        width, height = _image_size(width, height)
        _check_fov(fov_deg)
        eye = _vector(eye, "eye")
        with np.errstate(over="ignore"):  # checked next, in the caller's terms
            forward = _vector(target, "target") - eye
        if not np.isfinite(forward).all():
            raise CameraError(f"the camera's eye {eye.tolist()} and target are too far apart: "
                              "their difference overflows float64")
        f, r, u = _basis(forward, up)
        half_h = float(np.tan(np.radians(fov_deg) / 2.0))
        return cls(PINHOLE, eye, f, r, u, half_h * width / height, half_h, width, height)

    @classmethod
    def orthographic(
        cls, center, direction, up=None, *, view_height: float,
        width: int = 512, height: int | None = None,
    ) -> Camera:
        """Parallel projection; rays start on the image plane through ``center``; ``up`` as
        ``look_at``'s."""
        width, height = _image_size(width, height)
        f, r, u = _basis(direction, up)
        if not is_real(view_height):  # float() of a string or None raised Python's own error
            raise CameraError(f"view_height must be a number, got {view_height!r}")
        half_h = float(view_height) / 2.0
        return cls(
            ORTHOGRAPHIC, _vector(center, "center"), f, r, u,
            half_h * width / height, half_h, width, height,
        )

    @classmethod
    def cube_face(cls, position, face: str, size: int = 128) -> Camera:
        """One 90° face of a cube map centred at ``position`` (faces named +x, -x, ...)."""
        size, _ = _image_size(size, size)
        for name, forward, up in CUBE_FACES:
            if name == face:
                f, r, u = _basis(forward, up)
                return cls(PINHOLE, _vector(position, "position"), f, r, u, 1.0, 1.0, size, size)
        names = ", ".join(n for n, _, _ in CUBE_FACES)
        raise CameraError(f"unknown cube face {face!r}; use one of {names}")

    @classmethod
    def octahedral(cls, position, resolution: int = 64) -> Camera:
        """A light probe at ``position``: an R×R octahedral map of every direction; pixel
        (row, col) is texel (v, u) of ``kernels.octahedral`` (y up)."""
        resolution, _ = _image_size(resolution, resolution)
        return cls(OCTAHEDRAL, _vector(position, "probe position"), *_OCTAHEDRAL_BASIS, 1.0,
                   1.0, resolution, resolution)

    @property
    def params(self) -> np.ndarray:
        """The packed float64 layout the kernels read (see kernels.camera_rays)."""
        return np.concatenate(
            (
                [float(self.kind)], self.position, self.forward, self.right, self.up,
                [self.half_width, self.half_height],
            )
        ).astype(np.float64)

    def rays(self, side: int = 1, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Origins and directions of every ray the renderers cast (pixel-major): ``side``²
        a pixel, 1..16 as the renderers take."""
        side = integer_in(side, "samples per pixel side", 1, 16)
        return camera_ray_arrays(self.params, self.width, self.height, side, seed_value(seed))


def cube_cameras(position, size: int = 128) -> list[Camera]:
    """The six faces of a probe's cube map, in +x, -x, +y, -y, +z, -z order."""
    return [Camera.cube_face(position, name, size) for name, _, _ in CUBE_FACES]


def top_down_camera(bounds_min, bounds_max, *, size: int = 512, fov_deg: float = 90.0) -> Camera:
    """The EA thesis's setup (§5.1.1): centred above the map, looking straight down, placed so
    the 90° frustum just spans the map's horizontal extent at the ground. A scene taller than
    that (an object, not a map) is framed at its top instead, so the eye is never inside it."""
    _check_fov(fov_deg)  # before it divides: fov 0 leaked NumPy's divide warning
    lo, hi = _box(bounds_min, bounds_max)
    c = (lo + hi) / 2.0
    half_extent = max(hi[0] - lo[0], hi[2] - lo[2]) / 2.0
    distance = half_extent / np.tan(np.radians(fov_deg) / 2.0)
    base = lo[1] if lo[1] + distance > hi[1] else hi[1]
    eye = (c[0], base + distance, c[2])
    return Camera.look_at(eye, (c[0], lo[1], c[2]), (0.0, 0.0, -1.0), fov_deg=fov_deg, width=size)


def oblique_camera(bounds_min, bounds_max, *, size: int = 512, fov_deg: float = 90.0,
                   elevation_deg: float = 45.0) -> Camera:
    """Looking at the map centre from the south at the given elevation (45° by default)."""
    _check_fov(fov_deg)  # before it divides: fov 0 leaked NumPy's divide warning
    lo, hi = _box(bounds_min, bounds_max)
    c = (lo + hi) / 2.0
    half_extent = max(hi[0] - lo[0], hi[2] - lo[2]) / 2.0
    distance = 1.6 * half_extent / np.tan(np.radians(fov_deg) / 2.0)
    el = np.radians(elevation_deg)
    eye = c + distance * np.array([0.0, np.sin(el), np.cos(el)])
    return Camera.look_at(eye, c, fov_deg=fov_deg, width=size)


def orbit_camera(bounds_min, bounds_max, *, size: int = 512, fov_deg: float = 45.0,
                 azimuth_deg: float = 35.0, elevation_deg: float = 30.0) -> Camera:
    """A three-quarter view framing a box, for demos and quick looks."""
    _check_fov(fov_deg)  # before it divides: fov 0 leaked NumPy's divide warning
    lo, hi = _box(bounds_min, bounds_max)
    center = (lo + hi) / 2.0
    radius = float(np.linalg.norm(hi - lo)) / 2.0
    dist = radius / np.sin(np.radians(fov_deg) / 2.0) * 1.05
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    offset = dist * np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
    return Camera.look_at(center + offset, center, fov_deg=fov_deg, width=size)


def beam_camera(bounds_min, bounds_max, *, size: int = 256, fov_deg: float = 58.0) -> Camera:
    """In front of the box (+z), above its floor, looking down at the floor in front of its
    middle: for the EA thesis's shadow box, the grid and the whole beam of light."""
    lo, hi = _box(bounds_min, bounds_max)
    extent = float(max(hi[0] - lo[0], hi[2] - lo[2]))
    centre = (lo + hi) / 2.0
    eye = (centre[0] + 0.125 * extent, lo[1] + 0.4 * extent, hi[2] + 0.12 * extent)
    target = (centre[0], lo[1], centre[2] + 0.2 * extent)
    return Camera.look_at(eye, target, fov_deg=fov_deg, width=size)


def room_camera(bounds_min, bounds_max, *, size: int = 512, fov_deg: float = 70.0) -> Camera:
    """Inside the box, a quarter of its depth in from the +z face and three quarters up,
    looking down towards the lower middle of its -z face: the Cornell box (or a room) as a
    person standing in it sees it, floor and blocks included. The eye sits a little off the
    box's centre lines, so it is inside any probe grid of 2, 3 or 4 probes an axis fitted
    to the box and off its lattice planes, where the probe cage would be ambiguous."""
    lo, hi = _box(bounds_min, bounds_max)
    c = (lo + hi) / 2.0
    extent = hi - lo
    eye = (c[0] + 0.07 * extent[0], lo[1] + 0.72 * extent[1], lo[2] + 0.74 * extent[2])
    target = (c[0], lo[1] + 0.3 * extent[1], lo[2])
    return Camera.look_at(eye, target, fov_deg=fov_deg, width=size)


def ortho_top_camera(bounds_min, bounds_max, *, size: int = 512) -> Camera:
    """Orthographic, straight down, the view just spanning the box's horizontal extent.

    The image is the same from any height; the eye sits one extent above the box, above
    the coarse nodes' boxes and the beam's reach, so that the beam bounds every block. From
    one voxel above the top, a third of the 512² desert's blocks (256² image) had no bound:
    their rays began at the eye, inside coarse nodes (whose hits then had no entry face),
    and took 4.2 steps a ray at LOD 0 and 3.5 at LOD 2 against 3.2 from above (6.0 and 5.3
    while rays from the camera walked the pyramid down from its top)."""
    lo, hi = _box(bounds_min, bounds_max)
    c = (lo + hi) / 2.0
    extent = float(max(hi[0] - lo[0], hi[2] - lo[2]))
    return Camera.orthographic((c[0], hi[1] + max(extent, 1.0), c[2]), (0.0, -1.0, 0.0),
                               (0.0, 0.0, -1.0), view_height=extent, width=size)


def framing_camera(points, *, size: int = 512) -> Camera:
    """An orbit view framing every point (for example a scene's corners and its probes)."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    if not len(points) or not np.isfinite(points).all():
        raise CameraError("a framing camera needs at least one point, every one finite")
    lo, hi = points.min(axis=0), points.max(axis=0)
    pad = np.maximum((hi - lo) * 0.02, 0.5)
    return orbit_camera(lo - pad, hi + pad, size=size)


#: Named views of a scene's box: vertical field of view (None: orthographic or cube face)
#: and what each is for. ``preset_camera`` builds them.
CAMERA_PRESETS = {
    "top": (90.0, "the EA thesis's setup: centred above the map, 90° looking straight down"),
    "oblique": (90.0, "the map centre from the south at 45° elevation"),
    "orbit": (45.0, "a three-quarter view framing the whole box"),
    "ortho-top": (None, "orthographic, straight down over the whole map"),
    "beam": (58.0, "in front of the box above its floor (the shadow box's beam)"),
    "room": (70.0, "inside the box, towards its -z face (Cornell box, probe grids)"),
    **{f"cube{face}": (None, f"the {face} face of a cube map at the box centre")
       for face, _, _ in CUBE_FACES},
}


def preset_camera(name: str, bounds_min, bounds_max, *, size: int = 512,
                  fov_deg: float | None = None) -> Camera:
    """The preset view ``name`` of the box (see ``CAMERA_PRESETS``); ``fov_deg`` overrides
    the preset's field of view where it has one."""
    name = "cube+x" if name == "cube" else name
    if name not in CAMERA_PRESETS:
        raise CameraError(f"unknown camera {name!r}; use {', '.join(CAMERA_PRESETS)} "
                            "or --eye/--target")
    fov = CAMERA_PRESETS[name][0] if fov_deg is None else fov_deg
    if fov is not None:
        _check_fov(fov)
    lo, hi = _box(bounds_min, bounds_max)
    if name.startswith("cube"):
        return Camera.cube_face((lo + hi) / 2.0, name[4:], size=size)
    if name == "ortho-top":
        return ortho_top_camera(lo, hi, size=size)
    make = {"top": top_down_camera, "oblique": oblique_camera, "orbit": orbit_camera,
            "beam": beam_camera, "room": room_camera}[name]
    return make(lo, hi, size=size, fov_deg=fov)


def check_camera(value, user: str) -> None:
    """A clear error where ``user`` (a function's name) was given something other than a
    ``Camera``: it failed deep inside, on the first attribute it read (``'NoneType' object
    has no attribute 'width'``)."""
    if not isinstance(value, Camera):
        raise VoxfieldError(f"{user} needs a voxfield Camera (voxfield.render.Camera and its "
                            f"presets), got {type(value).__name__}")
