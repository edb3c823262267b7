"""Solve for the error threshold that meets a ray budget or a quality target (EA §5.1.4's
"simple optimisation problem"), by bisection on monotone curves.

The ray count never rises with the threshold (a larger threshold refines a subset), so a
ray budget has a well-defined smallest threshold; PSNR falls with the threshold in practice,
and the search returns the largest threshold whose PSNR still meets the target.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from voxfield.error_table.table import THESIS_DECAY
from voxfield.errors import VoxfieldError
from voxfield.metrics import psnr, psnr_text
from voxfield.progress import progress_bar
from voxfield.render.camera import Camera
from voxfield.render.error_aware import render_error_aware
from voxfield.render.primary import render_reference
from voxfield.svo.octree import Octree


@dataclass
class Calibration:
    """The chosen threshold and every evaluation made on the way; ``psnr`` is NaN where
    the target was a ray budget (no reference is rendered then)."""

    threshold: float
    rays: int
    steps: int
    psnr: float
    target: dict
    trail: list[dict] = field(default_factory=list)

    def as_dict(self) -> dict:
        """The record a study writes: no ``psnr`` key where none was measured, so that a
        ``null`` PSNR in JSON means only what it means elsewhere, an image equal to the
        reference."""
        record = {"threshold": self.threshold, "rays": self.rays, "steps": self.steps}
        if not math.isnan(self.psnr):
            record["psnr"] = self.psnr
        return {**record, "target": self.target, "trail": self.trail}


def calibrate_threshold(
    octree: Octree, camera: Camera, *, target_rays: int | None = None,
    target_psnr: float | None = None, decay: float = THESIS_DECAY, base_lod: int | None = 2,
    low: float = 0.0, high: float = 1.0, iterations: int = 14, table=None, seed: int = 0,
    channel: str = "albedo",
    progress: bool = False,
) -> Calibration:
    """Bisection over ``[low, high]`` for ``target_rays`` (the smallest threshold whose ray
    count is at most the budget) or ``target_psnr`` (the largest threshold meeting it)."""
    if (target_rays is None) == (target_psnr is None):
        raise VoxfieldError("give exactly one of a ray budget or a PSNR target")
    if not low < high or iterations < 1:
        raise VoxfieldError("the threshold search needs low < high and at least one step")
    search_low, search_high = low, high
    reference = (render_reference(octree, camera, side=4, seed=seed, channel=channel)
                 if target_psnr else None)
    trail: list[dict] = []

    def evaluate(threshold: float) -> dict:
        result = render_error_aware(octree, camera, table, threshold=threshold, decay=decay,
                                    base_lod=base_lod, seed=seed, channel=channel)
        entry = {"threshold": threshold, "rays": result.total_rays, "steps": result.total_steps}
        if reference is not None:
            entry["psnr"] = psnr(reference.image, result.image)
        trail.append(entry)
        return entry

    def meets(entry: dict) -> bool:
        if target_rays is not None:
            return entry["rays"] <= target_rays
        return entry["psnr"] >= target_psnr

    # For rays, "meets" holds above the answer; for PSNR, below it.
    want_high = target_rays is not None
    with progress_bar(total=iterations, desc="calibrate", unit="step", enabled=progress) as bar:
        best = None
        for _ in range(iterations):
            mid = 0.5 * (low + high)
            entry = evaluate(mid)
            if meets(entry):
                best = entry
                if want_high:
                    high = mid
                else:
                    low = mid
            elif want_high:
                low = mid
            else:
                high = mid
            bar.update(1)
    if best is None:
        # Nothing met it: the bracket end left is the search's own end, the closest one.
        edge = evaluate(high if want_high else low)
        if not meets(edge):
            searched = f"no threshold in {search_low:g}..{search_high:g} meets"
            if want_high:
                raise VoxfieldError(f"{searched} the budget of {target_rays:,} rays: the "
                                    f"fewest, {edge['rays']:,}, come at threshold "
                                    f"{edge['threshold']:g}")
            raise VoxfieldError(f"{searched} the target of {target_psnr:g} dB: the best, "
                                f"{psnr_text(edge['psnr'])} dB, comes at threshold "
                                f"{edge['threshold']:g}")
        best = edge
    final_psnr = best.get("psnr", math.nan)
    target = {"rays": target_rays} if want_high else {"psnr": target_psnr}
    return Calibration(float(best["threshold"]), int(best["rays"]), int(best["steps"]),
                       float(final_psnr), target, trail)

