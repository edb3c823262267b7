"""Suns: a direction from azimuth and elevation, a sun colour and a sky colour.

Directions follow the terrain convention of ``voxfield.scene.terrain`` (north is −z, east is
+x, +y up): the azimuth is a compass bearing, clockwise seen from above, 0° north, 90° east,
180° south, 270° west; the elevation is the angle above the horizon. ``direction()`` points
from the scene *towards* the sun.

Colours are in the bake's units, not radiometric ones: a voxel's lit colour is
``albedo × (irradiance × cos θ × visibility + sky × sky visibility)``, so ``irradiance`` is
what an open face square to the sun receives and ``sky`` what an open, upward face receives
from the whole sky; both are linear RGB scaled so that open ground at noon stays near 1.

The four times of day
---------------------
The EA thesis bakes four "times of day" per area (ch. 4, fig. 4.1: "the emission of the
voxels during different times of day ... depends only on the position of the sun and the
self-shadowing of the terrain") but never states the sun's angles. We chose angles that
reproduce what §5.3 says about each time (a northern-hemisphere sun; the thesis's terrain
is from Horizon Zero Dawn, set in the North American west):

========== ========== ===== ===== =============================================================
name       thesis     az °  el °  why
========== ========== ===== ===== =============================================================
morning    Time 0     110   40    brightest desert image (Table 5.19: 0.0864) yet as many
                                  refined rays as the low suns (Table 5.18): a mid-high sun
                                  that still casts shadows
noon       Time 2     180   65    fewest shadows: the desert needs far fewer adaptive rays
                                  (Table 5.18: 488,808 vs ~705,000) and the mountain lacks
                                  "large regions being in shade" (§5.3.3)
afternoon  Time 3     235   30    second-darkest desert (0.0541) and "large dark areas" in the
                                  mountain's fourth image (§5.3.3): a lower sun
evening    Time 1     280   12    darkest desert (0.0324, "lots of shadowed areas", §5.3.1);
                                  in the biomes area "almost the entire mountain is even in the
                                  shadow of the surrounding terrain" (§5.3.4): a low western sun
========== ========== ===== ===== =============================================================

Open flat ground gets 0.72 (morning), 0.57 (afternoon) and 0.25 (evening) of noon's
luminance with the colours below; the thesis's desert images have 1.18, 0.74 and 0.44 of
Time 2's (Table 5.19). Time 3 and Time 1 are darker in the same order, but the thesis gives no
sun colours or intensities (and its Time 0 is brighter than its least-shadowed Time 2, which
no elevation explains alone), so we match the shadows it describes, not its luminances.
``time0`` .. ``time3`` name the same suns in the thesis's order. The thesis's shadows are
black ("the luminance being 0 in those areas", §5.3.1): bake with ``sky_rays=0`` for that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from voxfield.errors import VoxfieldError
from voxfield.svo.channels import check_channel_name

__all__ = [
    "THESIS_TIMES",
    "TIMES_OF_DAY",
    "SunLight",
    "daylight",
    "parse_suns",
    "sun_at",
]

#: Sun colour with the sun at the zenith (open ground at our noon gets 0.76 + sky).
SUN_ZENITH = 0.85
#: Extinction per extra air mass for red, green, blue: low suns turn orange, then red.
EXTINCTION = np.array([0.09, 0.16, 0.32])
#: Sky colour on open upward ground by day; it fades out from 20° down to 6° below the horizon.
SKY_DAY = np.array([0.13, 0.17, 0.23])
_SKY_FULL_DEG = 20.0
_SKY_DARK_DEG = -6.0  # civil twilight ends


def _air_mass(elevation_deg: float) -> float:
    """Relative optical air mass (Kasten & Young 1989); 1 at the zenith, ~38 at the horizon."""
    return 1.0 / (
        math.sin(math.radians(elevation_deg)) + 0.50572 * (elevation_deg + 6.07995) ** -1.6364
    )


def daylight(elevation_deg: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Sun and sky colours for a sun at ``elevation_deg``: white overhead, reddened and dimmed
    by the longer path through the air when low, none below the horizon; the sky fades with
    the twilight."""
    if elevation_deg > 0.0:
        sun = SUN_ZENITH * np.exp(-EXTINCTION * (_air_mass(elevation_deg) - 1.0))
    else:
        sun = np.zeros(3)
    t = min(max((elevation_deg - _SKY_DARK_DEG) / (_SKY_FULL_DEG - _SKY_DARK_DEG), 0.0), 1.0)
    sky = SKY_DAY * (t * t * (3.0 - 2.0 * t))
    return tuple(float(v) for v in sun), tuple(float(v) for v in sky)


def _rgb(value, what: str) -> tuple[float, float, float]:
    try:
        rgb = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise VoxfieldError(f"{what} must be three numbers (R, G, B), got {value!r}") from None
    if len(rgb) != 3 or not all(math.isfinite(v) and v >= 0.0 for v in rgb):
        raise VoxfieldError(f"{what} must be three finite, non-negative numbers, got {value!r}")
    return rgb


@dataclass(frozen=True)
class SunLight:
    """One lighting condition; ``name`` becomes the baked channel's name."""

    name: str
    azimuth_deg: float
    elevation_deg: float
    irradiance: tuple[float, float, float]
    sky: tuple[float, float, float]

    def __post_init__(self) -> None:
        check_channel_name(self.name)
        for what in ("azimuth_deg", "elevation_deg"):
            value = getattr(self, what)
            if not isinstance(value, (int, float, np.number)) or not math.isfinite(value):
                raise VoxfieldError(f"sun {self.name!r}: {what} must be a finite number, "
                                    f"got {value!r}")
        if not -90.0 <= self.elevation_deg <= 90.0:
            raise VoxfieldError(f"sun {self.name!r}: elevation must be in [-90, 90] degrees, "
                                f"got {self.elevation_deg}")
        object.__setattr__(self, "azimuth_deg", float(self.azimuth_deg) % 360.0)
        object.__setattr__(self, "elevation_deg", float(self.elevation_deg))
        object.__setattr__(self, "irradiance", _rgb(self.irradiance, f"sun {self.name!r} colour"))
        object.__setattr__(self, "sky", _rgb(self.sky, f"sun {self.name!r} sky colour"))

    def direction(self) -> np.ndarray:
        """Unit vector towards the sun (float64, y up, north −z, east +x)."""
        az = math.radians(self.azimuth_deg)
        el = math.radians(self.elevation_deg)
        return np.array(
            [math.cos(el) * math.sin(az), math.sin(el), -math.cos(el) * math.cos(az)]
        )

    @property
    def above_horizon(self) -> bool:
        return self.elevation_deg > 0.0


def sun_at(name: str, azimuth_deg: float, elevation_deg: float) -> SunLight:
    """A sun with the colours ``daylight`` gives its elevation."""
    if not math.isfinite(elevation_deg) or not -90.0 <= elevation_deg <= 90.0:
        raise VoxfieldError(f"sun {name!r}: elevation must be in [-90, 90] degrees, "
                            f"got {elevation_deg}")
    sun, sky = daylight(elevation_deg)
    return SunLight(name, azimuth_deg, elevation_deg, sun, sky)


#: The four presets, in the order of the day (see the module docstring for the choice).
TIMES_OF_DAY: dict[str, SunLight] = {
    s.name: s
    for s in (
        sun_at("morning", 110.0, 40.0),
        sun_at("noon", 180.0, 65.0),
        sun_at("afternoon", 235.0, 30.0),
        sun_at("evening", 280.0, 12.0),
    )
}
#: The thesis's "Time 0" .. "Time 3" (§5.3) as our presets.
THESIS_TIMES = {"time0": "morning", "time1": "evening", "time2": "noon", "time3": "afternoon"}


def _number_name(value: float) -> str:
    return f"{value:g}".replace("-", "m").replace(".", "p").replace("+", "")


def _custom_sun(text: str) -> SunLight:
    """``AZ,EL`` or ``NAME=AZ,EL``."""
    name, _, angles = text.rpartition("=")
    parts = [p.strip() for p in angles.split(",")]
    try:
        az, el = (float(p) for p in parts)
    except ValueError:
        raise VoxfieldError(
            f"sun {text!r}: expected a time of day or AZIMUTH,ELEVATION in degrees "
            "(e.g. 135,30 or dawn=90,5)"
        ) from None
    if not (math.isfinite(az) and math.isfinite(el)):
        raise VoxfieldError(f"sun {text!r}: azimuth and elevation must be finite")
    name = name.strip() or f"sun_{_number_name(az)}_{_number_name(el)}"
    return sun_at(name, az, el)


def _named_sun(name: str) -> SunLight:
    key = name.strip().lower()
    key = THESIS_TIMES.get(key, key)
    if key not in TIMES_OF_DAY:
        known = ", ".join([*TIMES_OF_DAY, *THESIS_TIMES])
        raise VoxfieldError(f"unknown time of day {name.strip()!r}; known: {known}, "
                            "or give AZIMUTH,ELEVATION in degrees")
    return TIMES_OF_DAY[key]


def parse_suns(spec: str) -> list[SunLight]:
    """Suns from a command-line list: ``;``-separated items, each a comma-separated list of
    time-of-day names (``morning,noon``, ``time0``) or one sun ``AZ,EL`` / ``NAME=AZ,EL``.

    ``"all"`` is the four presets. Two suns may not share a name (it names their channel).
    """
    text = spec.strip()
    if not text:
        raise VoxfieldError("no sun given; name times of day (e.g. morning,noon) or AZ,EL")
    if text.lower() == "all":
        return list(TIMES_OF_DAY.values())
    suns: list[SunLight] = []
    for item in text.split(";"):
        item = item.strip()
        if not item:
            raise VoxfieldError(f"empty item in sun list {spec!r}")
        tokens = [t.strip() for t in item.rpartition("=")[2].split(",")]
        numeric = [_is_number(t) for t in tokens]
        if "=" in item or all(numeric):
            suns.append(_custom_sun(item))
        elif any(numeric):
            raise VoxfieldError(f"sun {item!r}: mixes names and numbers; separate suns "
                                "with ';' (e.g. noon;135,30)")
        else:
            suns.extend(_named_sun(t) for t in item.split(","))
    names = [s.name for s in suns]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise VoxfieldError(f"sun list names {', '.join(repeated)} more than once")
    return suns


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
