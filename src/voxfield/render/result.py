"""RenderResult: an image plus the per-pixel cost counters both theses measure."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from voxfield.render.image_io import png_bytes, shade_for_display


@dataclass
class RenderResult:
    """What every renderer returns; counters are hardware-independent cost measures.

    ``ray_count`` counts every ray cast for a pixel (including discarded ones),
    ``hit_count`` those that hit geometry, ``steps`` the octree nodes visited,
    ``finest_lod`` the smallest LOD any of the pixel's rays sampled (-1: nothing hit).
    """

    image: np.ndarray  # (H, W, 3) float32 linear RGB
    depth: np.ndarray  # (H, W) float32 mean hit distance, inf where nothing was hit
    normal: np.ndarray  # (H, W, 3) float32 mean face normal of hits
    ray_count: np.ndarray  # (H, W) int32
    hit_count: np.ndarray  # (H, W) int32
    steps: np.ndarray  # (H, W) int64
    finest_lod: np.ndarray  # (H, W) int8
    seconds: float = 0.0
    renderer: str = ""
    params: dict = field(default_factory=dict)
    maps: dict = field(default_factory=dict)  # renderer-specific per-pixel maps (H, W)

    def __repr__(self) -> str:  # the default printed every array in full
        h, w = self.image.shape[:2]
        return (f"RenderResult({self.renderer or 'render'}: {w}x{h}, "
                f"{int(self.ray_count.sum()):,} rays, {int(self.steps.sum()):,} steps, "
                f"{self.seconds:.3g} s)")

    @classmethod
    def allocate(cls, height: int, width: int, renderer: str = "") -> RenderResult:
        """Uninitialised buffers for a renderer's kernels to fill."""
        return cls(
            image=np.empty((height, width, 3), np.float32),
            depth=np.empty((height, width), np.float32),
            normal=np.empty((height, width, 3), np.float32),
            ray_count=np.empty((height, width), np.int32),
            hit_count=np.empty((height, width), np.int32),
            steps=np.empty((height, width), np.int64),
            finest_lod=np.empty((height, width), np.int8),
            renderer=renderer,
        )

    def buffers(self, rows: slice = slice(None)) -> tuple[np.ndarray, ...]:
        """The per-pixel arrays in kernel argument order, for a band of rows."""
        return (self.image[rows], self.depth[rows], self.normal[rows], self.ray_count[rows],
                self.hit_count[rows], self.steps[rows], self.finest_lod[rows])

    @property
    def shape(self) -> tuple[int, int]:
        return self.image.shape[:2]

    @property
    def total_rays(self) -> int:
        return int(self.ray_count.sum())

    @property
    def total_steps(self) -> int:
        return int(self.steps.sum())

    @property
    def covered_pixels(self) -> int:
        return int((self.hit_count > 0).sum())

    @property
    def mrays_per_second(self) -> float:
        return self.total_rays / self.seconds / 1e6 if self.seconds > 0 else float("nan")

    def _repr_png_(self) -> bytes:
        """Jupyter shows a result as ``voxfield render`` writes its PNG: lit by the display
        key light where it has face normals and shows albedo (``image`` itself stays the flat
        linear colour the metrics read; baked light, and renders without normals such as a
        probe set's environment lookups, show as they are)."""
        lit = bool(np.any(self.normal)) and self.params.get("channel", "albedo") == "albedo"
        return png_bytes(shade_for_display(self) if lit else self.image)

    def summary(self) -> dict:
        """Totals for reports (JSON-friendly)."""
        rays = self.total_rays
        return {
            "renderer": self.renderer,
            "width": int(self.shape[1]),
            "height": int(self.shape[0]),
            "rays": rays,
            "hits": int(self.hit_count.sum()),
            "covered_pixels": self.covered_pixels,
            "traversal_steps": self.total_steps,
            "steps_per_ray": self.total_steps / rays if rays else 0.0,
            "seconds": self.seconds,
            "mrays_per_second": self.mrays_per_second,
            **{k: v for k, v in self.params.items() if isinstance(v, (int, float, str))},
        }
