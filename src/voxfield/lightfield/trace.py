"""Ray queries answered from light probes with depth (probe thesis ch. 4-7).

``trace_single`` marches rays against one probe; ``trace_light_field`` answers each ray from
the 8-probe cage around its origin with the thesis's ordering and hand-off (and the ring of
probes outside a cage that lost it), falling back to the nearest probe as an environment map.
Both run the Numba kernels of ``kernels.probe_march`` and ``kernels.probe_multi`` in parallel
over rays; results are the same for any thread count.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from voxfield.checks import flag, is_integer, is_real, ray_arrays
from voxfield.errors import VoxfieldError
from voxfield.kernels import probe_march as pm
from voxfield.kernels import probe_multi as mk
from voxfield.lightfield.cuda_trace import trace_light_field_cuda
from voxfield.lightfield.packed import PackedProbes
from voxfield.parallel import thread_count, threads_for
from voxfield.probes.probe_set import ProbeSet
from voxfield.render.camera import unit_vectors
from voxfield.render.device import check_device

#: Result kinds, as stored in ``kind`` arrays.
MISS = pm.MISS
HIT = pm.HIT
UNKNOWN = pm.UNKNOWN
FALLBACK = pm.FALLBACK
KIND_NAMES = {MISS: "miss", HIT: "hit", UNKNOWN: "unknown", FALLBACK: "fallback"}


def kind_counts(kind: np.ndarray) -> str:
    """``"1,024 rays: 900 hit, 124 miss"``: the answers' kinds, for a short repr."""
    counts = [f"{int(np.count_nonzero(kind == k)):,} {name}" for k, name in KIND_NAMES.items()
              if np.any(kind == k)]
    return f"{len(kind):,} rays" + (": " + ", ".join(counts) if counts else "")

MARCHERS = {"march3d": pm.MARCH3D, "dda": pm.DDA, "hierarchical": pm.HIERARCHICAL}
EPSILON_MODES = {"footprint": pm.EPS_FOOTPRINT, "constant": pm.EPS_CONSTANT,
                 "adaptive": pm.EPS_ADAPTIVE, "adaptive-text": pm.EPS_ADAPTIVE_TEXT,
                 "angular": pm.EPS_ANGULAR, "slope": pm.EPS_SLOPE}
#: The epsilon modes that read each of ``LightFieldOptions``' epsilon parameters
#: (``kernels.probe_march.epsilon_at``, ``texel_event``); the others ignore it.
EPSILON_READERS = {"epsilon_value": ("constant", "slope", "footprint"),
                   "epsilon_k": ("adaptive", "adaptive-text", "angular"),
                   "epsilon_front": ("footprint",)}
COLOUR_FILTERS = ("bilinear", "nearest")
#: Which probe answers a hit's colour (``kernels.probe_multi.COLOUR_*``).
COLOUR_PROBES = {"footprint": mk.COLOUR_FOOTPRINT, "parallel": mk.COLOUR_PARALLEL}
ORDERINGS = {"signed-dot": mk.ORDER_SIGNED_DOT, "nearest": mk.ORDER_NEAREST,
             "fixed": mk.ORDER_FIXED}

#: The 3D march's longest step, in voxels (world units): a scene's thinnest solid is one
#: voxel thick, and a longer step can carry the march through it with no point inside,
#: the texels before and after it showing what lies beyond.
MAX_STEP = 1.0
#: The 3D march's most points per probe: a step of a sixteenth of a voxel across 4,096
#: voxels. More only makes a trace run for hours (a probe's march is one ray's inner loop).
MAX_MARCH_POINTS = 1 << 16


def march_step_problem(step, max_steps: int) -> str | None:
    """Why ``step`` (voxels) cannot be the 3D march's step with at most ``max_steps`` points
    per probe, or ``None``. The shortest step is ``1 / max_steps``: a finer march stops at
    its step cap before it has gone one voxel, so every probe hands the ray on unanswered;
    the longest is ``MAX_STEP``."""
    if is_real(step) and 1.0 / max_steps <= step <= MAX_STEP:
        return None
    return (f"the march step must be {1.0 / max_steps:g}..{MAX_STEP:g} voxels, got {step!r}: "
            f"with at most {max_steps} points per probe a shorter step stops before it has "
            f"gone one voxel, and a longer one can pass through a one-voxel wall")


@dataclass(frozen=True)
class LightFieldOptions:
    """How rays are marched against probes.

    ``marcher``: ``"march3d"`` (fixed world ``step``, at most ``max_steps`` points per probe;
    the step is ``1 / max_steps`` to ``MAX_STEP`` voxels, see ``march_step_problem``; past
    the probe's farthest surface the DDA finishes the ray),
    ``"dda"`` (texel by texel in octahedral space) or ``"hierarchical"`` (over the min-distance
    mips; same answers as ``"dda"``, fewer fetches).
    ``epsilon``: hit acceptance — ``"footprint"`` (the default: ``epsilon_value`` plus the
    depth one texel spans where the ray crosses it, from the stored surface's slope and the
    angle between ray and probe direction; ``kernels.probe_march.EPS_FOOTPRINT``; in front
    of the surface at most ``epsilon_front`` texel widths, so maps whose texels are finer
    than ``epsilon_value`` keep silhouettes as sharp as they resolve them; ``inf`` turns the
    cap off),
    ``"constant"`` (thickness ``epsilon_value`` world units),
    ``"adaptive"`` (thesis §7.1 as printed: ``k · tan θ · d(X, Y) · |α·β| · (1 - β·ν)``, θ the
    pixel angle given to the trace, ``k = epsilon_k``; see ``kernels.probe_march.epsilon_at``),
    ``"adaptive-text"`` (the same with ``(1 - α·ν)``, the form the thesis's text derives),
    ``"angular"`` (accept when the stored point is within ``epsilon_k · θ`` of the ray seen
    from its origin) or ``"slope"`` (``epsilon_value`` plus half the depth the texel's stored
    surface spans across the texel, from its stored normal). ``backface``: reject hits whose
    stored normal faces along the ray (§7.2).
    ``ordering``: first probe of each cage — ``"nearest"`` (the default, McGuire et al. 2017),
    ``"signed-dot"`` (max ``ω · S²(X - P)``, the thesis) or ``"fixed"`` (corner 0); the rest
    follow ``i + 3 mod 8``, and a probe that loses the ray further on re-forms the cage
    there. ``ring`` (on by default): when every probe of a cage loses the ray at the point
    it has reached, the probes one lattice step outside the cage try it from there, nearest
    first (``kernels.probe_multi.probe_ring``; off is the thesis, which stops at the cage).
    ``fallback``: when every probe loses the ray, answer with the nearest probe's radiance
    in direction ω (kind ``FALLBACK``) rather than ``UNKNOWN``.
    ``consensus`` (on by default): before a hit is taken, the other probes of the cage
    around the hit point are asked whether they see empty space there; if two do
    (``kernels.probe_multi.WITNESSES``), the ray marches on, and comes back to that hit only
    if every probe loses it behind.
    ``colour_probe``: which cage probe that sees a hit point answers its radiance:
    ``"footprint"`` (the default: the one whose texel is smallest on the surface there,
    right for view-independent radiance, which is what bakes store) or ``"parallel"`` (the
    one that sees it most nearly along the ray). ``colour_filter``: that probe is read
    ``"bilinear"`` over its bordered map (texels showing another surface left out) or at the
    ``"nearest"`` texel. ``refine_window`` (texel widths, at least as many voxels; 0: off):
    a hit that another probe of the cage around it sees behind a nearer surface is traced
    again by that probe over this stretch before it (``kernels.probe_multi.hit_in_front``:
    where two walls meet, the finding probe's texel may hold the far wall, so the ray passes
    the near one unseen), and the hit is then traced again against its colour probe within ±
    this stretch (``refine_hit``: the finding probe may see the surface through a wide,
    grazing texel; the sharpest view places it best).
    """

    marcher: str = "hierarchical"
    step: float = 0.25
    max_steps: int = 4096
    epsilon: str = "footprint"
    epsilon_value: float = 0.5
    epsilon_k: float = 1.0
    epsilon_front: float = 0.25
    backface: bool = False
    ordering: str = "nearest"
    fallback: bool = True
    consensus: bool = True
    colour_filter: str = "bilinear"
    colour_probe: str = "footprint"
    refine_window: float = 3.0
    ring: bool = True

    def __post_init__(self) -> None:
        for name, table in (("marcher", MARCHERS), ("epsilon", EPSILON_MODES),
                            ("ordering", ORDERINGS)):
            if getattr(self, name) not in table:
                raise VoxfieldError(f"unknown {name} {getattr(self, name)!r}; choose one of "
                                    f"{', '.join(table)}")
        if self.colour_probe not in COLOUR_PROBES:
            raise VoxfieldError(f"unknown colour probe rule {self.colour_probe!r}; choose one "
                                f"of {', '.join(COLOUR_PROBES)}")
        if self.colour_filter not in COLOUR_FILTERS:
            raise VoxfieldError(f"unknown colour filter {self.colour_filter!r}; choose one of "
                                f"{', '.join(COLOUR_FILTERS)}")
        if not is_integer(self.max_steps) or not 1 <= self.max_steps <= MAX_MARCH_POINTS:
            raise VoxfieldError(f"max_steps must be an integer in 1..{MAX_MARCH_POINTS}, got "
                                f"{self.max_steps!r}")
        problem = march_step_problem(self.step, self.max_steps)
        if problem is not None:
            raise VoxfieldError(problem)
        for name in ("consensus", "ring", "backface", "fallback"):
            flag(getattr(self, name), name)
        if not (_finite(self.epsilon_value) and self.epsilon_value >= 0):
            raise VoxfieldError(f"epsilon_value must be a distance >= 0, got "
                                f"{self.epsilon_value!r}")
        if not (is_real(self.epsilon_front) and self.epsilon_front >= 0):
            raise VoxfieldError(f"epsilon_front must be a number of texels >= 0 (inf: no cap), "
                                f"got {self.epsilon_front!r}")
        if not (_finite(self.refine_window) and self.refine_window >= 0):
            raise VoxfieldError(f"refine_window must be a number of texels >= 0 (0: off), got "
                                f"{self.refine_window!r}")
        if not (_finite(self.epsilon_k) and self.epsilon_k >= 0):
            raise VoxfieldError(f"epsilon_k must be a number >= 0, got {self.epsilon_k!r}")

    def params(self, pixel_angle: float) -> np.ndarray:
        """The kernels' float64 parameter array (layout ``kernels.probe_march.P_*``)."""
        out = np.zeros(pm.N_PARAMS)
        out[pm.P_EPSILON] = self.epsilon_value
        out[pm.P_K] = self.epsilon_k
        out[pm.P_THETA] = pixel_angle
        out[pm.P_STEP] = self.step
        out[pm.P_MAX_STEPS] = self.max_steps
        out[pm.P_BACKFACE] = 1.0 if self.backface else 0.0
        out[pm.P_CONSENSUS] = 1.0 if self.consensus else 0.0
        out[pm.P_BILINEAR] = 1.0 if self.colour_filter == "bilinear" else 0.0
        out[pm.P_COLOUR_PROBE] = COLOUR_PROBES[self.colour_probe]
        out[pm.P_FRONT] = self.epsilon_front
        out[pm.P_REFINE] = self.refine_window
        out[pm.P_RING] = 1.0 if self.ring else 0.0
        return out


def _finite(value) -> bool:
    return is_real(value) and math.isfinite(value)


@dataclass
class ProbeHits:
    """One probe's answer per ray. ``kind`` int8 (``HIT``/``MISS``/``UNKNOWN``); ``t``
    float64: the hit distance for a hit, ``tmax`` for a miss, how far the probe vouched for
    the ray for unknown; ``row``/``col`` int32 the answering texel (-1 unless hit; also set
    for an unknown from a 2D marcher: the texel where visibility was lost); ``radiance``
    (N, 3) float32, ``normal`` (N, 3) float32 and ``distance`` float32 (stored radial
    distance) of that texel (zero / inf where not hit); ``fetches`` (distance texels read)
    and ``steps`` int64."""

    kind: np.ndarray
    t: np.ndarray
    row: np.ndarray
    col: np.ndarray
    radiance: np.ndarray
    normal: np.ndarray
    distance: np.ndarray
    fetches: np.ndarray
    steps: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        return self.kind == HIT

    def __repr__(self) -> str:  # the default printed every array in full
        return f"{type(self).__name__}({kind_counts(self.kind)})"


@dataclass
class LightFieldHits:
    """The light field's answer per ray. ``kind`` int8: ``HIT``, ``MISS`` (a probe proved
    the segment empty), ``FALLBACK`` (every probe tried lost the ray; radiance is the nearest
    probe's in direction ω, ``t`` its stored distance there) or ``UNKNOWN`` (same, with
    fallback off). ``t`` float64 hit distance along the unit direction (``tmax`` for a
    miss); ``radiance`` / ``normal`` (N, 3) float32 and ``distance`` float32 (the answering
    texel's stored radial distance; zero / inf when there is none); ``probe`` int32 the
    answering probe (-1: none); ``probes_tried`` int32 (a hit came from the
    ``probes_tried``-th probe in the order); ``fetches`` and ``steps`` int64 summed over
    the probes tried."""

    kind: np.ndarray
    t: np.ndarray
    radiance: np.ndarray
    normal: np.ndarray
    distance: np.ndarray
    probe: np.ndarray
    probes_tried: np.ndarray
    fetches: np.ndarray
    steps: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        return self.kind == HIT

    def __repr__(self) -> str:  # the default printed every array in full
        return f"LightFieldHits({kind_counts(self.kind)})"

    @classmethod
    def empty(cls, n: int) -> LightFieldHits:
        """Buffers for ``n`` rays, in the dtypes the kernels write."""
        return cls(kind=np.empty(n, np.int8), t=np.empty(n),
                   radiance=np.empty((n, 3), np.float32), normal=np.empty((n, 3), np.float32),
                   distance=np.empty(n, np.float32), probe=np.empty(n, np.int32),
                   probes_tried=np.empty(n, np.int32), fetches=np.empty(n, np.int64),
                   steps=np.empty(n, np.int64))

    def summary(self) -> dict:
        """Counts of each kind and mean cost per ray."""
        n = max(len(self.kind), 1)
        out = {name: int(np.count_nonzero(self.kind == k)) for k, name in KIND_NAMES.items()}
        out.update(rays=len(self.kind), fetches_per_ray=float(self.fetches.sum()) / n,
                   steps_per_ray=float(self.steps.sum()) / n,
                   probes_per_ray=float(self.probes_tried.sum()) / n)
        return out


def checked_options(options) -> LightFieldOptions:
    """The trace's options: the defaults for None."""
    if options is None:
        return LightFieldOptions()
    if not isinstance(options, LightFieldOptions):
        raise VoxfieldError(f"options must be LightFieldOptions, got {type(options).__name__}")
    return options


def _rays(origins, dirs, tmin, tmax):
    o, d = ray_arrays(origins, dirs)
    d = np.ascontiguousarray(unit_vectors(d))
    n = len(o)
    # Copies: for 0 or 1 rays the broadcast view is already contiguous and stays read-only,
    # another type to Numba, so a probe render compiled its kernel again inside the timing.
    lo, hi = (_per_ray(value, n, name) for value, name in ((tmin, "tmin"), (tmax, "tmax")))
    if np.isnan(lo).any() or np.isnan(hi).any() or np.any(lo < 0) or np.isinf(lo).any():
        raise VoxfieldError("tmin must be finite and >= 0 and tmax not NaN")
    return o, d, lo, hi


def _per_ray(value, n: int, name: str) -> np.ndarray:
    """``value`` (a number, or one for each of the ``n`` rays) as a writable float64 array."""
    try:
        return np.array(np.broadcast_to(np.asarray(value, np.float64), (n,)))
    except (TypeError, ValueError):
        raise VoxfieldError(f"{name} must be a number or one number a ray ({n}), got "
                            f"{np.shape(value)} of {type(value).__name__}") from None


def _pixel_angle(value) -> float:
    if not (_finite(value) and 0 <= value < math.pi / 2):
        raise VoxfieldError(f"pixel angle must be in [0, π/2) radians, got {value!r}")
    return float(value)


def packed_probes(probes, user: str) -> PackedProbes:
    """``probes`` as the kernels read them: a ``PackedProbes`` as it is, a ``ProbeSet``
    packed here (on every call: pack it once, ``PackedProbes.from_probe_set``, to trace it
    many times)."""
    if isinstance(probes, PackedProbes):
        return probes
    if isinstance(probes, ProbeSet):
        return PackedProbes.from_probe_set(probes)
    raise VoxfieldError(f"{user} needs probes: a PackedProbes, or a ProbeSet from a bake; got "
                        f"{type(probes).__name__}")


def trace_single(packed: PackedProbes, probe: int, origins, dirs,
                 options: LightFieldOptions = LightFieldOptions(), tmin=0.0, tmax=math.inf,
                 *, pixel_angle: float = 0.0, threads: int | None = None) -> ProbeHits:
    """March rays ``o + t·d`` (``d`` normalised here; ``t`` in world units) with
    ``tmin <= t < tmax`` (scalars or per-ray arrays) against probe ``probe`` alone
    (``packed``: see ``packed_probes``)."""
    packed = packed_probes(packed, "trace_single")
    if not is_integer(probe) or not -packed.count <= probe < packed.count:
        raise VoxfieldError(f"probe index {probe!r} is not an integer in 0..{packed.count - 1}"
                            f" (or -{packed.count}..-1, counted from the last)")
    probe = int(probe) % packed.count
    options = checked_options(options)
    o, d, lo, hi = _rays(origins, dirs, tmin, tmax)
    n = len(o)
    kind = np.empty(n, np.int8)
    t = np.empty(n)
    row = np.empty(n, np.int32)
    col = np.empty(n, np.int32)
    fetches = np.empty(n, np.int64)
    steps = np.empty(n, np.int64)
    with thread_count(threads_for(n, threads)):
        mk.trace_single_rays(MARCHERS[options.marcher], EPSILON_MODES[options.epsilon],
                             options.params(_pixel_angle(pixel_angle)), packed.positions,
                             packed.mips, packed.mip_offsets, packed.mip_sizes, packed.normals,
                             packed.resolution, probe, o, d, lo, hi, kind, t, row, col,
                             fetches, steps)
    empty = _empty_segments(lo, hi)
    kind[empty], t[empty], row[empty], col[empty] = MISS, hi[empty], -1, -1
    fetches[empty] = steps[empty] = 0
    hit = kind == HIT
    radiance = np.zeros((n, 3), np.float32)
    normal = np.zeros((n, 3), np.float32)
    distance = np.full(n, np.inf, np.float32)
    radiance[hit] = packed.radiance[probe, row[hit], col[hit]]
    normal[hit] = packed.normals[probe, row[hit], col[hit]]
    distance[hit] = packed.distance[probe, row[hit], col[hit]]
    return ProbeHits(kind, t, row, col, radiance, normal, distance, fetches, steps)


def probe_field(packed: PackedProbes) -> mk.ProbeField:
    """The maps and grid of ``packed`` that the trace kernels read."""
    return mk.ProbeField(*(getattr(packed, name) for name in mk.ProbeField._fields))


def trace_light_field(packed: PackedProbes, origins, dirs,
                      options: LightFieldOptions = LightFieldOptions(), *,
                      pixel_angle: float = 0.0, tmin=0.0, tmax=math.inf,
                      threads: int | None = None, device: str = "cpu") -> LightFieldHits:
    """Answer rays ``o + t·d`` (``d`` normalised here) from the probe cage around each
    origin (Algorithms 4-6); ``pixel_angle`` is θ of the adaptive and angular ε (radians).
    ``device="cuda"`` traces them on a GPU (``lightfield.cuda_trace``) with the same
    results. ``packed``: see ``packed_probes``."""
    check_device(device)
    packed = packed_probes(packed, "trace_light_field")
    options = checked_options(options)
    if not packed.enabled.any():
        raise VoxfieldError("no probe of the set is enabled; bake some probes first")
    o, d, lo, hi = _rays(origins, dirs, tmin, tmax)
    out = LightFieldHits.empty(len(o))
    modes = (MARCHERS[options.marcher], EPSILON_MODES[options.epsilon],
             ORDERINGS[options.ordering], bool(options.fallback),
             options.params(_pixel_angle(pixel_angle)))
    if device == "cuda":
        trace_light_field_cuda(packed, modes, o, d, lo, hi, out)
    else:
        with thread_count(threads_for(len(o), threads)):
            mk.trace_light_field_rays(
                mk.TraceModes(*modes), probe_field(packed), mk.RayBatch(o, d, lo, hi),
                mk.LightFieldOutputs(*(getattr(out, name)
                                       for name in mk.LightFieldOutputs._fields)),
                numba.get_num_threads())
    empty = _empty_segments(lo, hi)
    if empty.any():  # nothing to find on [tmin, tmax): a miss no probe needed to prove
        out.kind[empty], out.t[empty], out.distance[empty] = MISS, hi[empty], np.inf
        out.radiance[empty] = out.normal[empty] = 0.0
        out.probe[empty] = -1
        out.probes_tried[empty] = out.fetches[empty] = out.steps[empty] = 0
    return out


def _empty_segments(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Rays whose segment ``tmin <= t < tmax`` holds no point (``tmax <= tmin``)."""
    return hi <= lo
