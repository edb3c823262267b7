"""Baked light probes (probe thesis ch. 4, §5.2): bake options, one probe's maps, a grid's set.

Every map is an R×R octahedral map laid out as ``kernels.octahedral`` defines it (row = v,
column = u, y up), without the one-texel border (``kernels.octahedral.add_border`` adds it):

- radiance: linear RGB, float16 (what an engine uploads; metrics read it as float32);
- distance: radial distance from the probe centre to the first surface along the texel-centre
  direction, float32, ``inf`` where the ray leaves the scene, 0 where the probe sits inside
  a voxel;
- normal: the hit face's unit normal, octahedral-encoded into two snorm16 channels (int16)
  with the same mapping as the maps themselves; ``NO_NORMAL`` in both channels where there is
  no face (a miss, or a probe inside a voxel).

Distance and normal always come from one exact ray per texel centre at LOD 0, whatever renderer
made the radiance, so a probe's depth is the octree's own ray-cast distance.
"""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, fields

import numpy as np

from voxfield.checks import is_integer, is_real, seed_value
from voxfield.error_table.table import THESIS_DECAY, THESIS_THRESHOLD
from voxfield.errors import VoxfieldError
from voxfield.kernels.octahedral import decode_normals_snorm16, encode_normals_snorm16
from voxfield.render.image_io import png_bytes
from voxfield.render.primary import LodOptions, ReferenceOptions
from voxfield.render.registry import RENDERERS

#: Radiance renderers a bake can use (``reference`` = side×side CMJ rays at LOD 0).
BAKE_RENDERERS = tuple(RENDERERS)
MIN_RESOLUTION = 4
MAX_RESOLUTION = 2048
#: Stored in both normal channels where a texel has no surface normal. No encoder output has
#: -32768 in both channels (the lower-left corner of the square, -y, encodes as -32767 there).
NO_NORMAL = -32768


@dataclass(frozen=True)
class BakeOptions:
    """How a probe is baked; immutable and JSON-round-trippable (``to_dict``/``from_dict``).

    ``resolution`` R: the side of every octahedral map, an even number in 4..2048. Even, so
    the octahedron's fold lines and the four axis directions in the square's plane fall on
    texel edges, never through texel centres (each texel lies in one octant). Powers of two
    give the min-distance mip chain exact halvings; other even sizes use the rule in
    ``min_distance_mips``.
    ``renderer`` makes the radiance: ``reference`` (``samples``² CMJ rays at LOD 0),
    ``lod`` (one ray at ``lod``, or with ``lod=None`` at the LOD the texel-footprint cone
    picks, ``cone_scale`` footprints per node), ``adaptive`` (EA §5.1.2, base LOD as
    ``lod``; its cone is always at scale 1) or ``error-aware`` (EA §5.1.3, base LOD as
    ``lod``, ``threshold``/``decay``).
    ``channel`` is the octree colour channel baked as radiance; ``seed`` the sampling seed.
    """

    resolution: int = 64
    renderer: str = "error-aware"
    channel: str = "albedo"
    samples: int = ReferenceOptions.side
    lod: int | None = None
    cone_scale: float = LodOptions.cone_scale
    threshold: float = THESIS_THRESHOLD
    decay: float = THESIS_DECAY
    seed: int = 0

    def __post_init__(self) -> None:
        r = self.resolution
        if not is_integer(r) or not MIN_RESOLUTION <= r <= MAX_RESOLUTION or r % 2:
            raise VoxfieldError(
                f"probe resolution must be an even integer in {MIN_RESOLUTION}..{MAX_RESOLUTION}"
                f" (a power of two for exact mip halvings), got {r!r}")
        if self.renderer not in BAKE_RENDERERS:
            raise VoxfieldError(f"unknown bake renderer {self.renderer!r}; choose one of "
                                f"{', '.join(BAKE_RENDERERS)}")
        if not isinstance(self.channel, str) or not self.channel:
            raise VoxfieldError(f"channel must be a colour channel name, got {self.channel!r}")
        if not is_integer(self.samples) or not 1 <= self.samples <= 16:
            raise VoxfieldError(f"samples (rays per texel side) must be in 1..16, "
                                f"got {self.samples!r}")
        if self.lod is not None and (not is_integer(self.lod) or self.lod < 0):
            raise VoxfieldError(f"lod must be None (texel-footprint cone) or an integer >= 0, "
                                f"got {self.lod!r}")
        if not (is_real(self.cone_scale) and math.isfinite(self.cone_scale)
                and self.cone_scale > 0):
            raise VoxfieldError(f"cone scale must be a positive number, got {self.cone_scale!r}")
        if not is_real(self.threshold) or math.isnan(self.threshold):
            raise VoxfieldError(f"threshold must be a number (inf: never refine, negative: "
                                f"always), got {self.threshold!r}")
        if not (is_real(self.decay) and math.isfinite(self.decay) and self.decay >= 0):
            raise VoxfieldError(f"decay must be a finite number >= 0, got {self.decay!r}")
        seed_value(self.seed)  # the renderers' seeds: 32-bit words

    @property
    def texels(self) -> int:
        return self.resolution * self.resolution

    def to_dict(self) -> dict:
        """Plain JSON values; a non-finite threshold is written as the string ``"inf"``."""
        out = asdict(self)
        if not math.isfinite(out["threshold"]):
            out["threshold"] = str(out["threshold"])
        return out

    @classmethod
    def from_dict(cls, data: dict) -> BakeOptions:
        """The options ``to_dict`` wrote; missing keys take their defaults."""
        if not isinstance(data, dict):
            raise VoxfieldError(f"bake options must be a mapping, got {type(data).__name__}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise VoxfieldError(f"unknown bake option(s): {', '.join(unknown)}")
        values = dict(data)
        if isinstance(values.get("threshold"), str):
            try:
                values["threshold"] = float(values["threshold"])
            except ValueError as exc:
                raise VoxfieldError(f"threshold {values['threshold']!r} is not a number") from exc
        return cls(**values)


@dataclass(frozen=True)
class BakeCost:
    """What baking one probe cost, per pass. ``radiance_*`` is the chosen renderer;
    ``geometry_*`` the exact texel-centre pass for distance and normal (one LOD-0 ray per
    texel; zero when the radiance pass already was that pass and was reused). Rays count
    every ray cast, discarded ones included; steps count octree nodes visited; seconds are
    kernel time (compilation excluded)."""

    radiance_rays: int = 0
    radiance_steps: int = 0
    radiance_seconds: float = 0.0
    geometry_rays: int = 0
    geometry_steps: int = 0
    geometry_seconds: float = 0.0

    @classmethod
    def from_record(cls, record: dict) -> BakeCost:
        """A cost read back from a probe record: counts are whole numbers and seconds finite,
        both non-negative, so totals over a set never overflow or turn NaN."""
        values = {}
        for name in COST_FIELDS:
            value = record[name]
            if not is_real(value) or not math.isfinite(value) or not 0 <= value < 2**53:
                raise ValueError(f"{name} is {value!r}, not a non-negative number")
            if not name.endswith("seconds"):
                if value != int(value):
                    raise ValueError(f"{name} is {value!r}, not a whole number")
                value = int(value)
            values[name] = value
        return cls(**values)

    @property
    def rays(self) -> int:
        return self.radiance_rays + self.geometry_rays

    @property
    def steps(self) -> int:
        return self.radiance_steps + self.geometry_steps

    @property
    def seconds(self) -> float:
        return self.radiance_seconds + self.geometry_seconds


COST_FIELDS = tuple(f.name for f in fields(BakeCost))


@dataclass
class ProbeMaps:
    """One baked probe: ``radiance`` (R, R, 3) float16 linear RGB, ``distance`` (R, R)
    float32 (inf: no surface), ``normal`` (R, R, 2) int16 snorm16 octahedral normals
    (``NO_NORMAL`` where none), and its ``cost``. A caller may rely on these dtypes and shapes,
    and on ``distance`` being bit-identical to ``float32`` of the LOD-0 ray cast along
    ``kernels.octahedral.texel_directions(R)`` from the probe position."""

    radiance: np.ndarray
    distance: np.ndarray
    normal: np.ndarray
    cost: BakeCost

    def __post_init__(self) -> None:
        r = self.distance.shape[0] if self.distance.ndim == 2 else -1
        if (self.distance.shape != (r, r) or self.radiance.shape != (r, r, 3)
                or self.normal.shape != (r, r, 2)):
            raise VoxfieldError(
                f"probe maps disagree in shape: radiance {self.radiance.shape}, distance "
                f"{self.distance.shape}, normal {self.normal.shape}")
        if (self.radiance.dtype != np.float16 or self.distance.dtype != np.float32
                or self.normal.dtype != np.int16):
            raise VoxfieldError("probe maps must be float16 radiance, float32 distance and "
                                "int16 normals")

    @classmethod
    def empty(cls, resolution: int) -> ProbeMaps:
        """A probe that was not baked: black, no surface in any direction, no cost."""
        r = int(resolution)
        return cls(np.zeros((r, r, 3), np.float16), np.full((r, r), np.inf, np.float32),
                   np.full((r, r, 2), NO_NORMAL, np.int16), BakeCost())

    @property
    def resolution(self) -> int:
        return int(self.distance.shape[0])

    @property
    def texels(self) -> int:
        return self.resolution ** 2

    @property
    def rays(self) -> int:
        return self.cost.rays

    @property
    def steps(self) -> int:
        return self.cost.steps

    @property
    def seconds(self) -> float:
        return self.cost.seconds

    def normal_vectors(self) -> np.ndarray:
        """(R, R, 3) float32 unit normals decoded from ``normal`` (zero where none)."""
        return decode_normals(self.normal)

    def cost_summary(self) -> dict:
        """Totals and per-texel figures of this probe's bake."""
        return _cost_summary({k: getattr(self.cost, k) for k in COST_FIELDS}, 1, self.texels)


@dataclass
class ProbeSet:
    """A baked probe grid: stacked maps (N, R, R, ...) in the grid's probe order, as
    ``ProbeMaps`` describes them, plus per-probe cost arrays (``cost[name]``, (N,), names in
    ``COST_FIELDS``), ``enabled`` (N,) (disabled probes hold ``ProbeMaps.empty``), the probe
    ``positions`` (N, 3), the ``grid`` and ``options`` it was baked with, and the
    ``fingerprint`` of the octree and channel (``Octree.fingerprint``)."""

    grid: object
    options: BakeOptions
    positions: np.ndarray
    enabled: np.ndarray
    radiance: np.ndarray
    distance: np.ndarray
    normal: np.ndarray
    cost: dict
    fingerprint: str

    def __repr__(self) -> str:  # the default printed every map in full
        r = self.options.resolution
        return (f"ProbeSet({len(self.positions)} probes, {int(np.count_nonzero(self.enabled))} "
                f"enabled, {r}x{r} maps, channel {self.options.channel!r})")

    def __post_init__(self) -> None:
        n, r = len(self.positions), self.options.resolution
        expected = {"positions": (n, 3), "enabled": (n,), "radiance": (n, r, r, 3),
                    "distance": (n, r, r), "normal": (n, r, r, 2)}
        for name, shape in expected.items():
            if np.shape(getattr(self, name)) != shape:
                raise VoxfieldError(f"probe set {name} has shape {np.shape(getattr(self, name))}"
                                    f", expected {shape}")
        if sorted(self.cost) != sorted(COST_FIELDS) or any(
                np.shape(v) != (n,) for v in self.cost.values()):
            raise VoxfieldError(f"probe set cost must hold (N,) arrays {', '.join(COST_FIELDS)}")

    @classmethod
    def assemble(cls, grid, options: BakeOptions, probes: Sequence[ProbeMaps | None],
                 fingerprint: str, positions=None) -> ProbeSet:
        """Stack per-probe results (``None`` for a disabled probe) in grid order: how a
        distributed or resumed bake turns its pieces into a set."""
        positions = np.asarray(grid.positions if positions is None else positions, np.float64)
        if len(probes) != len(positions):
            raise VoxfieldError(f"{len(probes)} probe results for {len(positions)} probes")
        empty = ProbeMaps.empty(options.resolution)
        maps = [empty if p is None else p for p in probes]
        if any(m.resolution != options.resolution for m in maps):
            raise VoxfieldError(f"every probe must be {options.resolution}² texels")
        return cls(
            grid=grid, options=options, positions=positions.reshape(-1, 3),
            enabled=np.array([p is not None for p in probes], bool),
            radiance=_stack([m.radiance for m in maps], (0, *empty.radiance.shape), np.float16),
            distance=_stack([m.distance for m in maps], (0, *empty.distance.shape), np.float32),
            normal=_stack([m.normal for m in maps], (0, *empty.normal.shape), np.int16),
            cost={k: np.array([getattr(m.cost, k) for m in maps],
                              np.float64 if k.endswith("seconds") else np.int64)
                  for k in COST_FIELDS},
            fingerprint=str(fingerprint),
        )

    @property
    def count(self) -> int:
        return len(self.positions)

    @property
    def resolution(self) -> int:
        return self.options.resolution

    def probe(self, index: int) -> ProbeMaps:
        """Probe ``index``'s maps (views into the stacked arrays)."""
        if not -self.count <= index < self.count:
            raise VoxfieldError(f"probe index {index} is outside 0..{self.count - 1}")
        cost = BakeCost(**{k: self.cost[k][index].item() for k in COST_FIELDS})
        return ProbeMaps(self.radiance[index], self.distance[index], self.normal[index], cost)

    def cost_summary(self) -> dict:
        """Totals over the baked probes, per probe and per texel (rays, steps, seconds)."""
        baked = int(self.enabled.sum())
        totals = {k: v.sum().item() for k, v in self.cost.items()}
        return {"probes": self.count, "baked": baked, "resolution": self.resolution,
                "renderer": self.options.renderer,
                **_cost_summary(totals, baked, self.resolution ** 2)}

    def distance_mips(self) -> list[np.ndarray]:
        """The conservative min-distance chain of every probe: ``min_distance_mips``."""
        return min_distance_mips(self.distance)

    def _repr_html_(self) -> str:
        """Jupyter shows a probe set as its cost summary beside its radiance maps (one tile
        per probe, in probe order, a texel apart; the first 64)."""
        s = self.cost_summary()
        r = self.resolution
        shown = min(self.count, 64)  # a notebook cell, not an atlas of thousands
        strip = np.ones((r, max(1, shown) * (r + 1) - 1, 3), np.float32)
        for i in range(shown):
            strip[:, i * (r + 1):i * (r + 1) + r] = self.radiance[i]
        atlas = base64.b64encode(png_bytes(strip)).decode("ascii")
        counts = " × ".join(str(int(c)) for c in np.asarray(self.grid.counts).reshape(-1))
        rows = [("probes", f"{s['baked']} of {s['probes']} baked, grid {counts}"),
                ("resolution", f"{s['resolution']}² texels"), ("renderer", s["renderer"]),
                ("rays / texel", f"{s['rays_per_texel']:.3f}"),
                ("steps / texel", f"{s['steps_per_texel']:.2f}")]
        table = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th>"
                        f"<td>{html.escape(str(v))}</td></tr>" for k, v in rows)
        return (f"<div style='display:flex;gap:1em;align-items:flex-start'><table>{table}"
                f"</table><img alt='radiance maps' style='image-rendering:pixelated;"
                f"min-height:64px' src='data:image/png;base64,{atlas}'></div>")


def _stack(arrays: list[np.ndarray], empty_shape: tuple, dtype) -> np.ndarray:
    return np.stack(arrays).astype(dtype, copy=False) if arrays else np.empty(empty_shape, dtype)


def _cost_summary(totals: dict, probes: int, texels: int) -> dict:
    rays = totals["radiance_rays"] + totals["geometry_rays"]
    steps = totals["radiance_steps"] + totals["geometry_steps"]
    seconds = totals["radiance_seconds"] + totals["geometry_seconds"]
    all_texels = probes * texels
    per = (lambda v: v / all_texels) if all_texels else (lambda v: 0.0)
    return {
        "rays": int(rays), "steps": int(steps), "seconds": float(seconds),
        "radiance_rays": int(totals["radiance_rays"]),
        "geometry_rays": int(totals["geometry_rays"]),
        "seconds_per_probe": float(seconds) / probes if probes else 0.0,
        "rays_per_texel": per(rays), "steps_per_texel": per(steps),
        "radiance_rays_per_texel": per(totals["radiance_rays"]),
        "radiance_steps_per_texel": per(totals["radiance_steps"]),
        "nanoseconds_per_texel": per(float(seconds)) * 1e9,
    }


def min_distance_mips(distance: np.ndarray) -> list[np.ndarray]:
    """Min-distance mip chain of (..., R, R) maps, level 0 (the maps, as float32) first, down
    to 1×1. Texel (i, j) of level k + 1 is the true minimum of texels (2i..2i+1, 2j..2j+1) of
    level k; for an odd side the last row and column of blocks are one texel thin (level k+1
    has ceil(n/2) texels a side). So every mip texel is <= every texel it covers: a ray
    marcher may skip a block whose minimum lies beyond the ray."""
    level = np.asarray(distance, np.float32)
    if level.ndim < 2 or level.shape[-1] != level.shape[-2] or level.shape[-1] < 1:
        raise VoxfieldError(f"distance maps must be (..., R, R), got {level.shape}")
    if np.isnan(level).any():
        raise VoxfieldError("distance maps hold NaN")
    chain = [level]
    while level.shape[-1] > 1:
        n = level.shape[-1]
        if n % 2:
            pad = [(0, 0)] * (level.ndim - 2) + [(0, 1), (0, 1)]
            level = np.pad(level, pad, constant_values=np.inf)
            n += 1
        blocks = level.reshape(*level.shape[:-2], n // 2, 2, n // 2, 2)
        level = blocks.min(axis=(-3, -1))
        chain.append(level)
    return chain


def encode_normals(normals: np.ndarray) -> np.ndarray:
    """(..., 3) normals → (..., 2) int16 snorm16 octahedral codes
    (``kernels.octahedral.encode_normals_snorm16``, the maps' own mapping: x then z);
    zero vectors (no surface) → ``NO_NORMAL`` in both channels."""
    n = np.asarray(normals, np.float64)
    flat = n.reshape(-1, 3)
    some = np.abs(flat).sum(axis=1) > 0.0
    codes = np.full((len(flat), 2), NO_NORMAL, np.int16)
    codes[some] = encode_normals_snorm16(flat[some])
    return codes.reshape(*n.shape[:-1], 2)


def decode_normals(codes: np.ndarray) -> np.ndarray:
    """(..., 2) snorm16 codes → (..., 3) float32 unit normals; ``NO_NORMAL`` → zero vector."""
    c = np.asarray(codes)
    if c.shape[-1:] != (2,) or not np.issubdtype(c.dtype, np.integer):
        raise VoxfieldError(f"normal codes must be (..., 2) integers, got {c.dtype} {c.shape}")
    flat = c.reshape(-1, 2)
    some = ~(flat == NO_NORMAL).all(axis=1)
    out = np.zeros((len(flat), 3), np.float32)
    out[some] = decode_normals_snorm16(flat[some])
    return out.reshape(*c.shape[:-1], 3)
