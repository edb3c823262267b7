"""Light-field ray queries from baked probes with depth (probe thesis ch. 4-7)."""

from voxfield.lightfield.packed import PackedProbes
from voxfield.lightfield.trace import (
    FALLBACK,
    HIT,
    KIND_NAMES,
    MISS,
    UNKNOWN,
    LightFieldHits,
    LightFieldOptions,
    ProbeHits,
    trace_light_field,
    trace_single,
)

__all__ = ["FALLBACK", "HIT", "KIND_NAMES", "MISS", "UNKNOWN", "LightFieldHits",
           "LightFieldOptions", "PackedProbes", "ProbeHits", "trace_light_field", "trace_single"]
