"""The machine's memory, and the one rule the commands plan by: refuse, before the work
starts, a job that would need more than ``MEMORY_SHARE`` of it (it would be killed for
memory part-way, exit 137 and not a word)."""

from __future__ import annotations

import os

from voxfield.errors import VoxfieldError

#: Share of the machine's RAM one job may plan to use; the rest is the system's and others'.
MEMORY_SHARE = 0.8


def physical_memory() -> int | None:
    """Bytes of RAM on this machine, or None where the OS does not say."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return None


def check_fits_in_memory(need: int, work: str, advice: str,
                         error: type[VoxfieldError] = VoxfieldError) -> None:
    """Raise ``error`` ("``work`` needs about N GiB, over 80% of this machine's M GiB;
    ``advice``") where ``need`` bytes pass ``MEMORY_SHARE`` of the RAM; nothing where the
    OS does not say how much there is."""
    memory = physical_memory()
    if memory is not None and need > MEMORY_SHARE * memory:
        raise error(f"{work} needs about {need / 2**30:.1f} GiB, over "
                    f"{MEMORY_SHARE:.0%} of this machine's {memory / 2**30:.1f} GiB; {advice}")
