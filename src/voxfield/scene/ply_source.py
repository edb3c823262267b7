"""What is wrong with a PLY file that trimesh cannot read, in plain words.

trimesh fails on a damaged PLY with its own internals (``IndexError: list index out of
range`` for a header cut short, ``ValueError: setting an array element with a sequence``
for a short ASCII line). The header is checked here before trimesh reads the file; the
ASCII body only once trimesh has failed on it (a walk over every line in Python).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

#: PLY's property types, under both their old and their sized names, and the 64-bit and
#: half types some writers use and trimesh reads.
TYPES = {"char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8",
         "uint8", "int16", "uint16", "int32", "uint32", "float32", "float64", "int64",
         "uint64", "float16"}
#: The header's last line (a comment may hold the words: only a line of its own counts).
_END_HEADER = re.compile(rb"^end_header[ \t\r]*$", re.M)
FORMATS = ("ascii", "binary_little_endian", "binary_big_endian")
#: A header longer than this is no header (a few hundred bytes is usual).
MAX_HEADER_BYTES = 1 << 20


@dataclass
class _Element:
    name: str
    count: int
    lists: list[bool] = field(default_factory=list)  # per property: a list?
    names: list[str] = field(default_factory=list)


@dataclass
class PlyHeader:
    format: str
    elements: list[_Element]
    body_line: int  # the file's line number (from 1) of end_header: the body follows it


def read_header(path: Path) -> PlyHeader | str:
    """The header of the PLY file ``path``, or what is wrong with it."""
    with open(path, "rb") as f:
        head = f.read(MAX_HEADER_BYTES)
    if head.split(b"\n", 1)[0].strip() != b"ply":
        return "not a PLY file (its first line is not 'ply')"
    found = _END_HEADER.search(head)
    if found is None:
        return "its header stops before 'end_header' (the file is cut short or damaged)"
    end = found.start()
    lines = head[:end].decode("ascii", errors="replace").splitlines()
    fmt = None
    elements: list[_Element] = []
    for number, line in enumerate(lines[1:], start=2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            if len(words) < 2 or words[1] not in FORMATS:
                return (f"header line {number}, {line.strip()!r}, names no PLY format "
                        f"({', '.join(FORMATS)})")
            fmt = words[1]
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                return f"header line {number}, {line.strip()!r}, is not 'element NAME COUNT'"
            elements.append(_Element(words[1], int(words[2])))
        elif words[0] == "property":
            is_list = len(words) == 5 and words[1] == "list"
            if not elements or not (is_list or len(words) == 3):
                return (f"header line {number}, {line.strip()!r}, is not a property of an "
                        "element ('property TYPE NAME' or 'property list COUNT_TYPE TYPE "
                        "NAME' after an 'element' line)")
            for kind in words[2:4] if is_list else words[1:2]:
                if kind not in TYPES:
                    return (f"header line {number}: property {words[-1]!r} has type "
                            f"{kind!r}, which PLY does not define")
            elements[-1].lists.append(is_list)
            elements[-1].names.append(words[-1])
        else:
            return f"header line {number}, {line.strip()!r}, is no PLY header line"
    if fmt is None:
        return "its header has no 'format' line"
    vertex = next((e for e in elements if e.name == "vertex"), None)
    if vertex is None or not {"x", "y", "z"} <= set(vertex.names):
        return "its header declares no vertex element with x, y and z properties"
    return PlyHeader(fmt, elements, len(lines) + 1)


def body_problem(path: Path, header: PlyHeader) -> str | None:
    """Where an ASCII body first disagrees with its header (a line with too few or too many
    values, a value that is no number, fewer lines than declared), or None."""
    if header.format != "ascii":
        return None
    text = path.read_bytes().decode("ascii", errors="replace")
    lines = text.splitlines()[header.body_line:]
    rows = ((n, line.split()) for n, line in enumerate(lines, header.body_line + 1)
            if line.strip())
    for element in header.elements:
        for i in range(element.count):
            number, values = next(rows, (None, None))
            if values is None:
                return (f"it ends after {i} of the {element.count} {element.name} lines its "
                        "header declares (cut short?)")
            need, at = 0, 0
            for is_list in element.lists:
                if is_list:
                    try:
                        length = int(values[at]) if at < len(values) else 0
                    except ValueError:
                        return f"line {number}: a list length {values[at]!r} is no whole number"
                    need, at = need + 1 + length, at + 1 + length
                else:
                    need, at = need + 1, at + 1
            if len(values) != need:
                return (f"line {number}: {element.name} {i} has {len(values)} values where "
                        f"the header's properties need {need}")
            for value in values:
                try:
                    float(value)
                except ValueError:
                    return f"line {number}: {value!r} is not a number"
    return None
