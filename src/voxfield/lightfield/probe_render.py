"""Camera images from baked probes alone: the light-field trace and its two baselines.

``render_from_probes`` casts one ray per pixel, through the pixel centre, and answers it from
the probes with no octree in sight: by the light-field ray query (``lightfield.trace``), by
an environment-map lookup or by a parallax-corrected box proxy (``lightfield.baselines``,
probe thesis §5.1). The result is a ``RenderResult`` like every octree renderer's, so the
same metrics, image writers and depth compositing apply.

Depth is t along the unit camera ray to the surface the answer came from (``inf`` where
none: a miss, the environment lookup, a ray that leaves the proxy box): the z the probe
thesis asks of a light-field renderer so it can be mixed with other renderers by depth
(§8.1.2), which ``composite_by_depth`` does.

Per-pixel maps (``RenderResult.maps``): ``probes_tried`` (probes the query consulted),
``texel_fetches`` (map texels read), ``result_kind`` (``KIND_NAMES``) and ``probe`` (the
probe that answered, -1 for none). ``steps`` holds the trace's march steps (0 for the
baselines, which do not march); ``ray_count`` is 1 and ``hit_count`` 1 where a surface was
found.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, is_dataclass

import numpy as np

from voxfield.errors import VoxfieldError
from voxfield.kernels.camera_rays import OCTAHEDRAL, ORTHOGRAPHIC, PINHOLE
from voxfield.kernels.octahedral import texel_of_direction
from voxfield.lightfield.baselines import (
    FETCHES,
    FILTERS,
    box_proxy_lookup,
    check_box,
    environment_lookup,
    lookup_maps,
    nearest_probe,
)
from voxfield.lightfield.packed import PackedProbes
from voxfield.lightfield.trace import KIND_NAMES, checked_options, trace_light_field
from voxfield.parallel import run_in_bands
from voxfield.render.camera import Camera
from voxfield.render.device import check_device
from voxfield.render.result import RenderResult

METHODS = ("light-field", "environment", "box-proxy")
#: About how long a band of rows takes: Ctrl-C is heard between bands.
BAND_SECONDS = 0.5
MAP_NAMES = ("probes_tried", "texel_fetches", "result_kind", "probe")
#: Above this share of a light-field render's pixels answered by no probe (fallback or
#: unknown), among those no probe proved empty, the render shows the fallback more than the
#: trace: the camera sees what the probes do not (inside closed space, outside the grid, far
#: above a surface layer). Proven-empty pixels (sky) stay out of the share, so that an object
#: seen against a wide sky is judged by its own pixels.
LOST_NOTE_SHARE = 0.25


def render_from_probes(probe_set, camera: Camera, *, method: str = "light-field",
                       options=None, box=None, filter: str = "bilinear", seed: int = 0,
                       threads: int | None = None, progress: bool = False,
                       packed=None, device: str = "cpu") -> RenderResult:
    """Render ``camera``'s view from ``probe_set`` (a ``ProbeSet``, or a ``PackedProbes``)
    by ``method``.

    ``light-field``: ``trace_light_field`` with ``options`` (``LightFieldOptions``, default
    options when None); ``packed`` may pass a ``PackedProbes`` already built from the set.
    ``environment``: the nearest enabled probe to the camera read in the ray direction.
    ``box-proxy``: the nearest probe read through the proxy box ``box`` = (lo, hi), by
    default ``probe_set_bounds(probe_set)``. ``filter`` is the baselines' texel filter.
    ``seed`` is accepted for symmetry with the octree renderers: rays go through pixel
    centres, so it changes nothing. Results do not depend on ``threads``. ``device="cuda"``
    traces the light field on a GPU (``lightfield.cuda_trace``), with the same image.
    """
    check_probe_device(device, method)

    if method not in METHODS:
        raise VoxfieldError(f"unknown probe render method {method!r}; choose one of "
                            f"{', '.join(METHODS)}")
    if not isinstance(camera, Camera):
        raise VoxfieldError(f"camera must be a voxfield Camera, got {type(camera).__name__}")
    if not all(hasattr(probe_set, name) for name in ("positions", "enabled", "radiance")):
        raise VoxfieldError(f"render_from_probes needs probes: a ProbeSet from a bake, or a "
                            f"PackedProbes; got {type(probe_set).__name__}")
    if filter not in FILTERS:
        raise VoxfieldError(f"unknown lookup filter {filter!r}; choose one of "
                            f"{', '.join(FILTERS)}")
    if not np.asarray(probe_set.enabled, bool).any():
        raise VoxfieldError("the probe set has no enabled probes; nothing to render from")
    h, w = camera.height, camera.width
    origins, dirs = camera.rays(side=1, seed=seed)
    result = _allocate(h, w, method)
    params: dict = {"method": method, "probes": int(len(probe_set.positions)),
                    "resolution": int(np.asarray(probe_set.radiance).shape[1])}

    if method == "light-field":
        query, trace_params = _light_field_query(probe_set, camera, options, packed, device)
        params.update(trace_params)
    else:
        lo, hi = probe_set_bounds(probe_set) if box is None else _checked_box(box)
        query = _baseline_query(probe_set, method, filter, (lo, hi), origins)
        params["filter"] = filter
        if method == "box-proxy":
            params["box"] = [np.asarray(lo, float).tolist(), np.asarray(hi, float).tolist()]

    def band(rows: slice) -> None:
        # run_in_bands starts with an empty band: the query then only loads its kernels.
        pixels = slice(rows.start * w, rows.stop * w)
        query(origins[pixels], dirs[pixels], result, rows)

    if device == "cuda":  # one launch for the image; the empty band compiles the kernel
        band(slice(0, 0))
        start = time.perf_counter()
        band(slice(0, h))
        result.seconds = time.perf_counter() - start
    else:
        # a light-field march costs from microseconds to milliseconds a ray; its rays are
        # traced one by one, so a band may be a single row
        result.seconds = run_in_bands(h, band, label=method, threads=threads,
                                      progress=progress, granule=1,
                                      seconds_per_band=BAND_SECONDS)
    result.params = params
    return result


def check_probe_device(device: str, method: str) -> None:
    """A clear error for a method that has no GPU path, then ``render.device``'s checks."""
    if device == "cuda" and method != "light-field":
        raise VoxfieldError(f"the {method} baseline runs on the CPU only; --device cuda "
                            "serves the light-field trace")
    check_device(device)


# --------------------------------------------------------------------------- methods


def _baseline_query(probe_set, method: str, filter: str, box, origins):
    """A band function for the environment or box-proxy lookup of the nearest probe; the
    maps of the probes nearest to ``origins`` (every ray's) are converted once, here."""
    kinds = result_kinds()
    maps = lookup_maps(probe_set, nearest_probe(probe_set, origins), filter)

    def query(origins, dirs, result, rows):
        n = len(dirs)
        if n == 0:  # load (or compile) the lookup kernels outside the timed region
            one = np.array([[0.0, 0.0, 1.0]])
            environment_lookup(probe_set, maps.probes[0], one, filter=filter, maps=maps)
            return
        probe = nearest_probe(probe_set, origins)
        if method == "environment":
            radiance, distance = environment_lookup(probe_set, probe, dirs, filter=filter,
                                                    maps=maps)
            normal = np.zeros((n, 3), np.float32)
            kind = np.full(n, kinds["environment"], np.int8)
        else:
            radiance, distance, normal = box_proxy_lookup(
                probe_set, probe, origins, dirs, box[0], box[1], filter=filter,
                return_normal=True, maps=maps)
            kind = np.where(np.isfinite(distance), kinds["hit"],
                            kinds["environment"]).astype(np.int8)
        _store(result, rows, radiance=radiance, depth=distance, normal=normal, kind=kind,
               probe=probe, tried=np.ones(n, np.int32),
               fetches=np.full(n, FETCHES[filter], np.int32), steps=np.zeros(n, np.int64))

    return query


def _light_field_query(probe_set, camera: Camera, options, packed, device: str):
    """A band function for ``trace_light_field``, and the options to record."""

    options = checked_options(options)
    if packed is None:
        packed = (probe_set if isinstance(probe_set, PackedProbes)
                  else PackedProbes.from_probe_set(probe_set))
    pixel_angle = pixel_angle_of(camera)
    kinds = result_kinds()

    def query(origins, dirs, result, rows):
        hits = trace_light_field(packed, origins, dirs, options, pixel_angle=pixel_angle,
                                 device=device)
        if len(dirs) == 0:
            return
        kind = np.asarray(hits.kind)
        found = np.isin(kind, [kinds["hit"]])
        depth = np.where(found, np.asarray(hits.t, np.float64), np.inf)
        _store(result, rows, radiance=hits.radiance, depth=depth, normal=hits.normal,
               kind=kind, probe=hits.probe, tried=hits.probes_tried, fetches=hits.fetches,
               steps=hits.steps)

    return query, {"options": _options_dict(options)}


def _store(result: RenderResult, rows: slice, *, radiance, depth, normal, kind, probe, tried,
           fetches, steps) -> None:
    """Write one band of per-ray answers into the image-shaped buffers."""
    w = result.shape[1]
    shape = (rows.stop - rows.start, w)
    depth = np.asarray(depth, np.float32).reshape(shape)
    found = np.isfinite(depth)
    result.image[rows] = np.asarray(radiance, np.float32).reshape(*shape, 3)
    result.depth[rows] = depth
    result.normal[rows] = np.asarray(normal, np.float32).reshape(*shape, 3)
    result.ray_count[rows] = 1
    result.hit_count[rows] = found
    result.steps[rows] = np.asarray(steps, np.int64).reshape(shape)
    # Probe depth is the LOD-0 ray cast's distance, so a found surface was sampled at LOD 0.
    result.finest_lod[rows] = np.where(found, 0, -1)
    maps = result.maps
    maps["probes_tried"][rows] = np.asarray(tried).reshape(shape)
    maps["texel_fetches"][rows] = np.asarray(fetches).reshape(shape)
    maps["result_kind"][rows] = np.asarray(kind).reshape(shape)
    maps["probe"][rows] = np.asarray(probe).reshape(shape)


def _allocate(h: int, w: int, method: str) -> RenderResult:
    result = RenderResult.allocate(h, w, f"probes:{method}")
    result.maps = {"probes_tried": np.zeros((h, w), np.int32),
                   "texel_fetches": np.zeros((h, w), np.int64),
                   "result_kind": np.zeros((h, w), np.int8),
                   "probe": np.full((h, w), -1, np.int64)}
    return result


def _options_dict(options) -> dict:
    """The trace options as plain values for the summary."""

    if not is_dataclass(options):
        return {}
    return {k: (v if isinstance(v, (int, float, str, bool)) or v is None else str(v))
            for k, v in asdict(options).items()}


def result_kinds() -> dict[str, int]:
    """Codes of the ``result_kind`` map: the trace's own (``lightfield.trace.KIND_NAMES``),
    plus ``environment`` for an answer read at infinity (the environment lookup, a ray that
    leaves the proxy box)."""

    codes = {name: int(code) for code, name in KIND_NAMES.items()}
    codes["environment"] = max(codes.values()) + 1
    return codes


def kind_names() -> dict[int, str]:
    """``result_kind`` code → name, for legends and summaries."""
    return {code: name for name, code in result_kinds().items()}


def lost_share(result: RenderResult) -> float:
    """The share of a light-field render's pixels no probe answered (``FALLBACK`` or
    ``UNKNOWN``) among those no probe proved empty; 0 for the baselines, which answer every
    ray."""
    kind = result.maps.get("result_kind")
    if result.params.get("method") != "light-field" or kind is None or kind.size == 0:
        return 0.0
    codes = result_kinds()
    lost = np.count_nonzero(np.isin(kind, [codes["fallback"], codes["unknown"]]))
    return lost_share_of(lost / kind.size, np.count_nonzero(kind == codes["miss"]) / kind.size)


def lost_share_of(lost: float, proven_empty: float) -> float:
    """``lost_share`` from the shares of all pixels that no probe answered (``lost``) and
    that a probe proved empty (``proven_empty``, the light field's misses)."""
    seen = 1.0 - proven_empty
    return 0.0 if seen <= 0.0 else min(1.0, lost / seen)


def probes_seeing(probe_set, point, enough: int | None = None) -> int:
    """How many enabled probes of ``probe_set`` see ``point``: every texel of the distance
    map within one of the point's direction reaches the point (less half a voxel). One
    texel's ray can pass beside a small solid that a far probe sees the point inside; the
    ring around it cannot. A camera no probe sees stands in solid, or in space no probe
    looked into: every ray it casts starts where the probes know nothing. With ``enough``
    the count stops there: whether any probe sees a point needs one, not a loop over a
    grid of thousands."""
    point = np.asarray(point, np.float64)
    positions = np.asarray(probe_set.positions, np.float64)
    distance = np.asarray(probe_set.distance)
    resolution = distance.shape[-1]
    seeing = 0
    for index in np.flatnonzero(np.asarray(probe_set.enabled, bool)):
        offset = point - positions[index]
        length = float(np.linalg.norm(offset))
        if length == 0.0:
            seeing += 1
        else:
            row, col = texel_of_direction(*(offset / length), resolution)
            around = distance[index, max(row - 1, 0):row + 2, max(col - 1, 0):col + 2]
            seeing += int(around.min() >= length - 0.5)
        if enough is not None and seeing >= enough:
            break
    return seeing


def hidden_eye_note(probe_set, view: Camera) -> str | None:
    """What to say when a pinhole camera's eye stands inside the probe grid's box where no
    probe sees it (``probes_seeing``), or ``None``. The light field answers a ray from
    there as if it started in open space: inside menger.vox's 3x3x3 grid it read a picture
    of surfaces the eye cannot see, its rays "hits" (no lost-pixels note); elsewhere the
    probes lose every ray, and the lost-pixels note gives a share but not the cause. An eye
    outside the box is where its rays enter it, not a point the probes must see."""
    if view.kind != PINHOLE:
        return None
    eye = np.asarray(view.position, np.float64)
    lo, hi = probe_set_bounds(probe_set)
    if not (np.all(lo <= eye) and np.all(eye <= hi)) or probes_seeing(probe_set, eye, 1):
        return None
    where = ", ".join(f"{v:.4g}" for v in eye)
    return (f"no probe of this set sees the camera's eye at ({where}): it stands in solid or "
            "where no probe looked, and the light field answers its rays as if it stood in "
            "open space")


def lost_rays_note(share: float, probes: str, *, fallback: bool = True) -> str | None:
    """What to say when no probe answered more than ``LOST_NOTE_SHARE`` of a light-field
    render's pixels not proven empty (``share``, from ``lost_share``, of ``probes``: "the
    3x3x3 grid"), or ``None``. ``fallback``: whether those pixels show the fallback (off,
    they are left unknown, black)."""
    if share <= LOST_NOTE_SHARE:
        return None
    shown = "show the fallback" if fallback else "are left unknown (black; --no-fallback)"
    return (f"{100 * share:.0f}% of the light field's pixels that no probe proved empty were "
            f"answered by no probe of {probes} (every probe the ray reached lost it): they "
            f"{shown}, not the trace")


def pixel_angle_of(camera: Camera) -> float:
    """The angle one pixel subtends at the image centre (radians; 0 for orthographic views,
    whose rays are parallel): what an adaptive epsilon scales with."""

    if camera.kind == ORTHOGRAPHIC:
        return 0.0
    if camera.kind == OCTAHEDRAL:
        return math.sqrt(4.0 * math.pi) / camera.height
    return 2.0 * math.atan(camera.half_height / camera.height)


def _checked_box(box) -> tuple[np.ndarray, np.ndarray]:
    try:
        lo, hi = box
    except (TypeError, ValueError):
        raise VoxfieldError("the proxy box must be a pair of corners (lo, hi)") from None
    return check_box(lo, hi)


# --------------------------------------------------------------------------- bounds


def probe_set_bounds(probe_set) -> tuple[np.ndarray, np.ndarray]:
    """The box a probe set was fitted to: the union of its grid's cells, each probe at a cell
    centre (``ProbeGrid.fit``'s default margin of half a spacing, as ``--grid NXxNYxNZ``
    uses), which is the scene's voxel box for a grid fitted to the scene. A grid without a
    lattice gets the probes' bounding box."""
    grid = getattr(probe_set, "grid", None)
    lattice = None
    if all(hasattr(grid, k) for k in ("origin", "spacing", "counts")):
        lattice = (grid.origin, grid.spacing, grid.counts)
    elif hasattr(probe_set, "grid_origin"):  # a PackedProbes
        lattice = (probe_set.grid_origin, probe_set.grid_spacing, probe_set.grid_counts)
    if lattice is not None:
        origin, spacing, counts = (np.asarray(v, np.float64) for v in lattice)
        return origin - 0.5 * spacing, origin + (counts - 0.5) * spacing
    positions = np.asarray(probe_set.positions, np.float64).reshape(-1, 3)
    return positions.min(axis=0) - 0.5, positions.max(axis=0) + 0.5


# --------------------------------------------------------------------------- compositing


def composite_by_depth(a: RenderResult, b: RenderResult) -> RenderResult:
    """Per pixel the nearer of two renders of the same view (probe thesis §8.1.2).

    Image, depth, normal and finest LOD come from whichever has the smaller depth; a tie
    (both ``inf`` included) keeps ``a``, so ``a`` supplies the background. Ray, hit and step
    counts add up (both renders were paid for). Maps both results hold are picked per pixel
    like the image; ``maps["source"]`` says which render won (0: ``a``, 1: ``b``).
    """
    if a.shape != b.shape:
        raise VoxfieldError(f"cannot composite renders of different sizes: {a.shape} and "
                            f"{b.shape}")
    if np.isnan(a.depth).any() or np.isnan(b.depth).any():
        raise VoxfieldError("a depth buffer holds NaN; cannot tell which surface is nearer")
    take_b = b.depth < a.depth

    def pick(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        mask = take_b if x.ndim == 2 else take_b[..., None]
        return np.where(mask, y, x)

    maps = {k: pick(a.maps[k], b.maps[k]) for k in a.maps
            if k in b.maps and np.shape(a.maps[k]) == np.shape(b.maps[k])}
    maps["source"] = take_b.astype(np.int8)
    return RenderResult(
        image=pick(a.image, b.image).astype(np.float32),
        depth=pick(a.depth, b.depth).astype(np.float32),
        normal=pick(a.normal, b.normal).astype(np.float32),
        ray_count=(a.ray_count + b.ray_count).astype(np.int32),
        hit_count=(a.hit_count + b.hit_count).astype(np.int32),
        steps=(a.steps + b.steps).astype(np.int64),
        finest_lod=pick(a.finest_lod, b.finest_lod).astype(np.int8),
        seconds=a.seconds + b.seconds,
        renderer=f"composite({a.renderer}, {b.renderer})",
        params={"a": a.renderer, "b": b.renderer},
        maps=maps,
    )
