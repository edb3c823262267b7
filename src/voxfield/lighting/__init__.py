"""Baked lighting: sun and sky light for named times of day, stored as colour channels."""

from voxfield.lighting.sun import THESIS_TIMES, TIMES_OF_DAY, SunLight, parse_suns, sun_at
from voxfield.lighting.sun_bake import BakeReport, bake_sun_lighting, sun_visibility

__all__ = [
    "THESIS_TIMES",
    "TIMES_OF_DAY",
    "BakeReport",
    "SunLight",
    "bake_sun_lighting",
    "parse_suns",
    "sun_at",
    "sun_visibility",
]
