"""Triangle meshes: the TriangleMesh container and ``load_mesh`` for OBJ (own parser), glTF, PLY.

OBJ goes through our own parser because trimesh 5.2 silently mis-parses negative (relative)
face indices, which the Cornell boxes use. glTF/GLB/PLY go through trimesh.

Colour conventions (all colours end up linear RGB, see DESIGN.md §4):

- MTL ``Kd`` and ``Ke`` are used as given: they are reflectance/radiance values, conventionally
  linear, even though many exporters write display-looking numbers.
- ``map_Kd`` texels and 8-bit vertex colours (PLY, OBJ ``v x y z r g b``) are sRGB-encoded and
  decoded with ``srgb_to_linear``; glTF ``COLOR_0`` and ``baseColorFactor`` are linear by the
  glTF spec, its ``baseColorTexture`` is sRGB.
- The colour of a surface point is ``face_color × vertex colour × texture`` (each factor present
  only when the mesh has it): the glTF rule, and the MTL spec's "map_Kd is multiplied by Kd".
"""

from __future__ import annotations

import io
import warnings
from dataclasses import dataclass
from itertools import chain
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from voxfield.errors import DataNotFoundError, SceneFormatError
from voxfield.scene.gltf_source import prepared_gltf
from voxfield.scene.ply_source import body_problem, read_header
from voxfield.scene.polygons import triangulate
from voxfield.scene.voxel_scene import srgb_to_linear

#: Linear colour of surfaces that name no material (or a material we could not find); glTF's
#: default material is white instead, as its specification says.
DEFAULT_COLOR = (0.8, 0.8, 0.8)

#: File suffixes ``load_mesh`` understands.
MESH_SUFFIXES = (".obj", ".gltf", ".glb", ".ply")


@dataclass(frozen=True)
class TriangleMesh:
    """Triangles with linear colours, in the file's own units and axes (+y up by convention).

    ``vertices`` V×3 float64; ``triangles`` T×3 int64; ``face_color`` T×3 float32 (material
    colour, always present); ``vertex_color`` optional V×3 float32 multiplier; ``uv`` optional
    T×3×2 float32 per-corner texture coordinates (v = 0 at the image bottom, OBJ/OpenGL style);
    ``face_texture`` optional T int32 index into ``textures`` (-1: untextured);
    ``textures`` linear H×W×3 float32 images (row 0 = image top); ``face_emission`` optional
    T×3 float32 linear emitted radiance (MTL ``Ke``, glTF ``emissiveFactor``).
    """

    vertices: np.ndarray
    triangles: np.ndarray
    face_color: np.ndarray
    vertex_color: np.ndarray | None = None
    uv: np.ndarray | None = None
    face_texture: np.ndarray | None = None
    textures: tuple[np.ndarray, ...] = ()
    face_emission: np.ndarray | None = None
    name: str = "mesh"

    def __post_init__(self) -> None:
        v = np.asarray(self.vertices, dtype=np.float64)
        t = np.asarray(self.triangles)
        where = f"mesh {self.name!r}"
        if v.ndim != 2 or v.shape[1] != 3:
            raise SceneFormatError(f"{where}: vertices must be V×3, got shape {v.shape}")
        if t.ndim != 2 or t.shape[1] != 3:
            raise SceneFormatError(f"{where}: triangles must be T×3, got shape {t.shape}")
        if len(v) == 0 or len(t) == 0:
            raise SceneFormatError(
                f"{where} is empty ({len(v)} vertices, {len(t)} triangles); nothing to voxelize"
            )
        if not np.issubdtype(t.dtype, np.integer):
            raise SceneFormatError(f"{where}: triangle indices must be integers, got {t.dtype}")
        t = t.astype(np.int64, copy=False)
        if t.min() < 0 or t.max() >= len(v):
            raise SceneFormatError(
                f"{where}: triangle indices must lie in [0, {len(v)}), found {t.min()}..{t.max()}"
            )
        if not np.isfinite(v).all():
            raise SceneFormatError(f"{where}: vertex positions contain NaN or infinite values")
        n_t = len(t)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "triangles", t)
        object.__setattr__(self, "face_color", _rgb(self.face_color, n_t, "face_color", where))
        if self.vertex_color is not None:
            vc = _rgb(self.vertex_color, len(v), "vertex_color", where)
            object.__setattr__(self, "vertex_color", vc)
        if self.face_emission is not None:
            fe = _rgb(self.face_emission, n_t, "face_emission", where, upper=None)
            object.__setattr__(self, "face_emission", fe)
        self._check_texturing(n_t, where)

    def _check_texturing(self, n_t: int, where: str) -> None:
        textures = tuple(np.asarray(img, dtype=np.float32) for img in self.textures)
        for img in textures:
            if img.ndim != 3 or img.shape[2] != 3 or img.shape[0] == 0 or img.shape[1] == 0:
                raise SceneFormatError(f"{where}: textures must be H×W×3, got {img.shape}")
        object.__setattr__(self, "textures", textures)
        if self.uv is None and self.face_texture is None:
            return
        if self.uv is None or self.face_texture is None:
            raise SceneFormatError(f"{where}: uv and face_texture come together")
        with np.errstate(over="ignore"):  # past float32's range: infinite, refused below
            uv = np.asarray(self.uv, dtype=np.float32)
        ft = np.asarray(self.face_texture).astype(np.int32)
        if uv.shape != (n_t, 3, 2):
            raise SceneFormatError(f"{where}: uv must be {n_t}×3×2, got {uv.shape}")
        if ft.shape != (n_t,) or (len(ft) and (ft.min() < -1 or ft.max() >= len(textures))):
            raise SceneFormatError(f"{where}: face_texture must index the {len(textures)} textures")
        if not np.isfinite(uv[ft >= 0]).all():
            raise SceneFormatError(f"{where}: texture coordinates contain NaN or infinite values")
        object.__setattr__(self, "uv", uv)
        object.__setattr__(self, "face_texture", ft)

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Min and max corner of the vertices the triangles use."""
        used = self.vertices[np.unique(self.triangles)]
        return used.min(axis=0), used.max(axis=0)

    @property
    def extents(self) -> np.ndarray:
        lo, hi = self.bounds
        return hi - lo

    def __len__(self) -> int:
        return len(self.triangles)


def _rgb(values, n: int, what: str, where: str, upper: float | None = 1.0) -> np.ndarray:
    with np.errstate(over="ignore"):  # past float32's range: infinite, refused just below
        arr = np.asarray(values, dtype=np.float32)
    if arr.shape != (n, 3):
        raise SceneFormatError(f"{where}: {what} must be {n}×3, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise SceneFormatError(f"{where}: {what} holds NaN or infinite values")
    return np.clip(arr, 0.0, upper)


def load_mesh(path: str | Path) -> TriangleMesh:
    """Read an OBJ (+MTL, textures), glTF/GLB or PLY file as one linear-colour TriangleMesh.

    Scene files are flattened with their node transforms applied. Raises SceneFormatError for
    missing, malformed, empty or non-finite meshes.
    """
    path = Path(path)
    if not path.is_file():
        raise DataNotFoundError(f"mesh file {path} does not exist (or is not a file)")
    suffix = path.suffix.lower()
    if suffix == ".obj":
        mesh = _load_obj(path)
    elif suffix in MESH_SUFFIXES:
        mesh = _load_with_trimesh(path)
    else:
        raise SceneFormatError(
            f"{path}: unsupported mesh format {suffix!r}; use one of {', '.join(MESH_SUFFIXES)}"
        )
    _check_extents(mesh, path)
    return mesh


def _check_extents(mesh: TriangleMesh, path: Path) -> None:
    with np.errstate(over="ignore"):  # the overflow is the finding, reported below
        ext = mesh.extents
    if not np.isfinite(ext).all():
        raise SceneFormatError(
            f"{path}: the mesh's extents {ext.tolist()} overflow: its vertices lie too far "
            "apart to measure or voxelize")
    if ext.max() <= 0.0:
        raise SceneFormatError(
            f"{path}: mesh extents {ext.tolist()} are degenerate (all vertices at one point)"
        )


# --------------------------------------------------------------------------------------------
# OBJ + MTL


@dataclass
class _Material:
    kd: tuple[float, float, float] = DEFAULT_COLOR
    ke: tuple[float, float, float] = (0.0, 0.0, 0.0)
    map_kd: Path | None = None


def _load_obj(path: Path) -> TriangleMesh:
    text = _read_text(path)
    v_rows: list[str] = []
    vt_rows: list[str] = []
    f_rows: list[str] = []
    f_mat: list[int] = []
    f_nv: list[int] = []
    f_nvt: list[int] = []
    mat_names: list[str] = []
    mat_index: dict[str, int] = {}
    libs: list[str] = []
    current = -1
    for raw in text.splitlines():
        if "#" in raw:
            raw = raw.split("#", 1)[0]
        parts = raw.split(None, 1)
        if not parts:
            continue
        key = parts[0]
        rest = parts[1] if len(parts) > 1 else ""
        if key == "v":
            v_rows.append(rest)
        elif key == "f":
            f_rows.append(rest)
            f_mat.append(current)
            f_nv.append(len(v_rows))
            f_nvt.append(len(vt_rows))
        elif key == "vt":
            vt_rows.append(rest)
        elif key == "usemtl":
            name = rest.strip()
            if name not in mat_index:
                mat_index[name] = len(mat_names)
                mat_names.append(name)
            current = mat_index[name]
        elif key == "mtllib":
            libs.append(rest.strip())
        elif key in ("vn", "vp", "o", "g", "s", "l", "p", "mg", "cstype", "deg", "curv", "surf"):
            continue
        # Unknown statements are ignored, as OBJ readers conventionally do.
    if not v_rows or not f_rows:
        raise SceneFormatError(
            f"{path}: OBJ holds {len(v_rows)} vertices and {len(f_rows)} faces; need both"
        )
    vertices, vcolor = _parse_vertices(v_rows, path)
    uv_table = _parse_uv_table(vt_rows, path) if vt_rows else None
    corners_v, corners_vt, counts = _parse_faces(f_rows, path)
    face_nv = np.repeat(np.asarray(f_nv, dtype=np.int64), counts)
    face_nvt = np.repeat(np.asarray(f_nvt, dtype=np.int64), counts)
    vi = _resolve(corners_v, face_nv, len(vertices), "vertex", path)
    has_vt = corners_vt != 0
    vti = np.full(len(corners_vt), -1, dtype=np.int64)
    if has_vt.any():
        n_vt = 0 if uv_table is None else len(uv_table)
        vti[has_vt] = _resolve(corners_vt[has_vt], face_nvt[has_vt], n_vt, "texture", path)

    # Convex polygons fanned from their first corner, concave ones ear-clipped.
    corner = triangulate(counts, vi, vertices)
    face_of_tri = np.repeat(np.arange(len(counts)), counts - 2)
    triangles = vi[corner]

    materials = _load_materials(path, libs, mat_names)
    face_mat = np.asarray(f_mat, dtype=np.int64)[face_of_tri]
    table = [materials.get(name) for name in mat_names]
    missing = sorted({n for n, m in zip(mat_names, table, strict=True) if m is None})
    if missing and (materials or not libs):  # a missing library was already reported
        warnings.warn(
            f"{path}: materials {missing} are not defined in its MTL files; "
            f"using grey {DEFAULT_COLOR}",
            stacklevel=3,
        )
    table = [m if m is not None else _Material() for m in table]
    white = vcolor is not None  # vertex colours alone should not be dimmed by a default grey
    default = _Material(kd=(1.0, 1.0, 1.0)) if white else _Material()
    table.append(default)  # index -1: faces before any usemtl
    kd = np.array([m.kd for m in table], dtype=np.float32)
    ke = np.array([m.ke for m in table], dtype=np.float32)
    face_color = kd[face_mat]
    face_emission = ke[face_mat] if ke.any() else None

    uv = face_texture = None
    textures: list[np.ndarray] = []
    tex_of_mat = np.full(len(table), -1, dtype=np.int32)
    for i, m in enumerate(table):
        if m.map_kd is not None:
            img = _read_texture(m.map_kd, path)
            if img is not None:
                tex_of_mat[i] = len(textures)
                textures.append(img)
    if textures:
        face_texture = tex_of_mat[face_mat]
        tri_vt = vti[corner]
        lacking = (tri_vt < 0).any(axis=1) & (face_texture >= 0)
        if lacking.any():
            warnings.warn(
                f"{path}: {int(lacking.sum())} textured triangles have no texture coordinates; "
                "they use the plain material colour",
                stacklevel=3,
            )
            face_texture[lacking] = -1
        uv = np.zeros((len(triangles), 3, 2), dtype=np.float32)
        ok = face_texture >= 0
        if ok.any():  # none are where the file has no 'vt' at all
            uv[ok] = uv_table[tri_vt[ok]]
    return TriangleMesh(
        vertices=vertices,
        triangles=triangles,
        face_color=face_color,
        vertex_color=vcolor,
        uv=uv,
        face_texture=face_texture,
        textures=tuple(textures),
        face_emission=face_emission,
        name=path.stem,
    )


def _read_text(path: Path) -> str:
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise SceneFormatError(f"{path}: cannot read the file ({exc})") from exc
    if b"\0" in data[:4096]:
        raise SceneFormatError(f"{path}: looks binary, not a text OBJ/MTL file")
    # Keywords and numbers are ASCII; names may be UTF-8 (undecodable bytes are replaced), and
    # a UTF-8 byte-order mark (as .NET writers put first) is no part of the first statement.
    # A backslash at the end of a line continues it.
    return data.decode("utf-8-sig", errors="replace").replace("\\\r\n", " ").replace("\\\n", " ")


def _numbers(rows: list[str], what: str, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """All numbers of ``rows`` as one float64 array, plus how many each row held."""
    split = [r.split() for r in rows]
    counts = np.fromiter(map(len, split), dtype=np.int64, count=len(split))
    try:
        flat = np.array(list(chain.from_iterable(split)), dtype=np.float64)
    except ValueError as exc:
        raise SceneFormatError(f"{path}: malformed {what} line ({exc})") from exc
    return flat, counts


def _parse_vertices(rows: list[str], path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    flat, counts = _numbers(rows, "vertex ('v')", path)
    width = int(counts[0])
    if (counts != width).any() or width not in (3, 4, 6):
        bad = int(np.argmax((counts != width) | (counts < 3)))
        raise SceneFormatError(
            f"{path}: vertex {bad + 1} has {int(counts[bad])} numbers; every 'v' line needs "
            "x y z [w] or x y z r g b, the same form throughout"
        )
    table = flat.reshape(-1, width)
    vertices = table[:, :3].copy()
    # Refused here, before any arithmetic on them: NumPy would print its own warning at each
    # step that met the NaN (a note apiece on the command line) before the mesh's own check.
    finite = np.isfinite(vertices).all(axis=1)
    if not finite.all():
        bad = int(np.argmin(finite))
        raise SceneFormatError(
            f"{path}: vertex {bad + 1} is at {' '.join(rows[bad].split()[:3])}; every "
            "coordinate must be a finite number, not NaN or infinite (nor past ±1.8e308)")
    colour = None
    if width == 6:
        rgb = table[:, 3:6]
        if np.isfinite(rgb).all() and rgb.max() > 1.0:
            rgb = rgb / 255.0  # some writers use 0..255
        colour = srgb_to_linear(np.clip(np.nan_to_num(rgb), 0.0, 1.0))
    return vertices, colour


def _parse_uv_table(rows: list[str], path: Path) -> np.ndarray:
    flat, counts = _numbers(rows, "texture coordinate ('vt')", path)
    if (counts < 1).any() or (counts > 3).any():
        raise SceneFormatError(f"{path}: 'vt' lines need 1 to 3 numbers")
    if (counts == counts[0]).all():
        table = flat.reshape(-1, int(counts[0]))
    else:
        table = np.zeros((len(counts), 3))
        cols = np.arange(len(flat)) - np.repeat(np.cumsum(counts) - counts, counts)
        table[np.repeat(np.arange(len(counts)), counts), cols] = flat
    uv = np.zeros((len(table), 2), dtype=np.float32)
    with np.errstate(over="ignore"):  # past float32's range: infinite, refused where used
        uv[:, : min(2, table.shape[1])] = table[:, :2]
    return uv


def _parse_faces(rows: list[str], path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-corner raw vertex and texture indices (0 = absent) and corners per face."""
    split = [r.split() for r in rows]
    counts = np.fromiter(map(len, split), dtype=np.int64, count=len(split))
    if (counts < 3).any():
        bad = int(np.argmax(counts < 3))
        raise SceneFormatError(f"{path}: face {bad + 1} has {int(counts[bad])} corners; need ≥ 3")
    tokens = list(chain.from_iterable(split))
    try:
        if not any("/" in r for r in rows):
            return np.array(tokens, dtype=np.int64), np.zeros(len(tokens), np.int64), counts
        fields = [t.split("/") for t in tokens]
        v = np.array([f[0] for f in fields], dtype=np.int64)
        vt = np.array([f[1] if len(f) > 1 and f[1] else "0" for f in fields], dtype=np.int64)
    except (ValueError, OverflowError) as exc:  # an index past int64 overflows
        raise SceneFormatError(f"{path}: malformed face ('f') line ({exc})") from exc
    return v, vt, counts


def _resolve(raw: np.ndarray, defined: np.ndarray, total: int, what: str, path: Path):
    """1-based and negative (relative to what was defined so far) OBJ indices → 0-based."""
    if (raw == 0).any():
        raise SceneFormatError(f"{path}: a face uses {what} index 0; OBJ indices start at 1")
    idx = np.where(raw < 0, defined + raw, raw - 1)
    bad = (idx < 0) | (idx >= total)
    if bad.any():
        i = int(np.argmax(bad))
        raise SceneFormatError(
            f"{path}: a face refers to {what} {int(raw[i])}, outside the {total} defined "
            f"({int(defined[i])} before that face)"
        )
    return idx


def _load_materials(obj_path: Path, libs: list[str], wanted: list[str]) -> dict[str, _Material]:
    materials: dict[str, _Material] = {}
    if not wanted:
        return materials
    for lib in libs:
        candidates = [lib] if (obj_path.parent / lib).is_file() else lib.split()
        for name in candidates:
            mtl = obj_path.parent / name.replace("\\", "/")
            if not mtl.is_file():
                warnings.warn(
                    f"{obj_path}: material library {name} not found; "
                    f"surfaces without materials are grey {DEFAULT_COLOR}",
                    stacklevel=4,
                )
                continue
            materials.update(_parse_mtl(mtl))
    return materials


def _parse_mtl(path: Path) -> dict[str, _Material]:
    out: dict[str, _Material] = {}
    cur: _Material | None = None
    for raw in _read_text(path).splitlines():
        if "#" in raw:
            raw = raw.split("#", 1)[0]
        parts = raw.split(None, 1)
        if not parts:
            continue
        key, rest = parts[0], (parts[1].strip() if len(parts) > 1 else "")
        if key == "newmtl":
            cur = out.setdefault(rest, _Material())
        elif cur is None:
            continue
        elif key in ("Kd", "Ke"):
            vals = rest.split()
            if not vals or vals[0] in ("spectral", "xyz"):
                continue  # spectral and CIE XYZ forms are not supported: keep the default
            try:
                nums = [float(x) for x in vals[:3]]
            except ValueError as exc:
                raise SceneFormatError(f"{path}: malformed {key} line {rest!r}") from exc
            rgb = (nums[0],) * 3 if len(nums) < 3 else tuple(nums)
            # Colours are stored as float32: a value past its range would overflow there (and
            # NaN fails the comparison too).
            if not np.abs(rgb).max() <= np.finfo(np.float32).max:
                raise SceneFormatError(f"{path}: {key} {rest!r} is not a finite colour")
            if key == "Kd":
                cur.kd = rgb
            else:
                cur.ke = rgb
        elif key == "map_Kd":
            cur.map_kd = _texture_path(path, rest)
    return out


def _texture_path(mtl: Path, rest: str) -> Path | None:
    """The file a ``map_Kd`` line names, skipping options such as ``-s 1 1 1``."""
    rest = rest.replace("\\", "/")
    whole = mtl.parent / rest
    if whole.is_file():
        return whole
    tokens = rest.split()
    return mtl.parent / tokens[-1] if tokens else None


def _read_texture(path: Path, owner: Path) -> np.ndarray | None:
    try:
        if path.exists() and not path.is_file():  # a pipe would wait for a writer for ever
            raise OSError(f"{path} is a pipe, device or folder, not an image file")
        with Image.open(path) as img:
            rgb = np.asarray(img.convert("RGB"), dtype=np.float32) / 255.0
    except (OSError, UnidentifiedImageError, ValueError, Image.DecompressionBombError) as exc:
        warnings.warn(
            f"{owner}: texture {path} cannot be read ({exc}); using the material colour",
            stacklevel=4,
        )
        return None
    return srgb_to_linear(rgb)


# --------------------------------------------------------------------------------------------
# glTF / GLB / PLY through trimesh


def _load_with_trimesh(path: Path) -> TriangleMesh:
    # heavy: trimesh loads only when a mesh file is read
    import trimesh

    gltf = path.suffix.lower() in (".gltf", ".glb")
    # trimesh reports broken glTF JSON as a missing file and reads what it cannot decode as
    # zeros: the file is checked (and its emission strengths folded in) first.
    source = prepared_gltf(path) if gltf else None
    header = None if gltf else read_header(path)
    if isinstance(header, str):
        raise SceneFormatError(f"{path}: {header}")
    try:
        # trimesh's arithmetic on what it reads (a node scaled by 1e300, a PLY float of 1e300)
        # warns wherever it overflows, a note apiece on the command line; the vertices it
        # hands back are checked once, below.
        with np.errstate(all="ignore"):
            if source is None:
                scene = trimesh.load_scene(str(path), process=False)
            else:
                scene = trimesh.load_scene(
                    file_obj=io.BytesIO(source), file_type=path.suffix.lower()[1:],
                    process=False, resolver=trimesh.resolvers.FilePathResolver(str(path)))
            parts = [g for g in scene.dump() if isinstance(g, trimesh.Trimesh) and len(g.faces)]
    except FileNotFoundError as exc:  # a buffer or image the file names
        raise SceneFormatError(f"{path}: a file it refers to is not there ({exc})") from exc
    except Exception as exc:  # trimesh raises many kinds for broken files, in its own terms
        raise SceneFormatError(f"{path}: {_unreadable(path, header)}") from exc
    if not parts:
        problem = body_problem(path, header) if header is not None else None
        raise SceneFormatError(f"{path}: {problem or 'holds no triangles'}")
    for g in parts:
        _check_finite(np.asarray(g.vertices, np.float64), path, gltf)
    pieces = [_from_trimesh(g, gltf) for g in parts]
    return _concatenate(pieces, path.stem)


def _unreadable(path: Path, header) -> str:
    """Why trimesh could not read a file whose header (PLY) or JSON (glTF) checked out:
    where a PLY's ASCII body first disagrees with its header, else plain words. trimesh's
    own message names its internals ("UnboundLocalError: ... 'access'")."""
    if header is None:
        return ("cannot be read as a glTF mesh: its data is damaged, or uses what this "
                "reader does not support")
    return body_problem(path, header) or ("cannot be read as a PLY mesh: its data does not "
                                          "match its header (damaged or cut short)")


def _check_finite(vertices: np.ndarray, path: Path, gltf: bool) -> None:
    """Refuse a vertex trimesh read as NaN or infinite: written so, past the range of the
    type the file stores it in, or (glTF) moved there by its nodes' transforms."""
    finite = np.isfinite(vertices).all(axis=1)
    if finite.all():
        return
    where = ", ".join(f"{c:g}" for c in vertices[int(np.argmin(finite))])
    if gltf:
        raise SceneFormatError(f"{path}: a vertex lands at ({where}) once its nodes' "
                               "transforms are applied; every coordinate must stay a finite "
                               "number, not NaN or infinite")
    raise SceneFormatError(f"{path}: a vertex reads as ({where}); every coordinate must be a "
                           "finite number, not NaN or infinite, within the range of the type "
                           "the file declares for it")


def _from_trimesh(geom, gltf: bool) -> dict:
    """One trimesh geometry → TriangleMesh fields (textures as a list). glTF's vertex colours
    are linear and its primitives without a material white (the spec's default material)."""
    # heavy: trimesh loads only when a mesh file is read
    from trimesh.visual.color import ColorVisuals
    from trimesh.visual.texture import TextureVisuals

    v = np.asarray(geom.vertices, dtype=np.float64)
    f = np.asarray(geom.faces, dtype=np.int64)
    n_t = len(f)
    part = {
        "vertices": v,
        "triangles": f,
        "face_color": np.tile(np.float32((1.0, 1.0, 1.0) if gltf else DEFAULT_COLOR),
                              (n_t, 1)),
        "vertex_color": None,
        "uv": None,
        "textures": [],
        "face_emission": None,
    }
    visual = geom.visual
    if isinstance(visual, ColorVisuals):
        decode = _unit_linear if gltf else _unit_srgb
        if visual.kind == "vertex":
            part["vertex_color"] = decode(visual.vertex_colors)
            part["face_color"] = np.ones((n_t, 3), np.float32)
        elif visual.kind == "face":
            part["face_color"] = decode(visual.face_colors)
    elif isinstance(visual, TextureVisuals):
        mat = visual.material
        factor = getattr(mat, "baseColorFactor", None)
        image = getattr(mat, "baseColorTexture", None)
        if factor is None and image is None:  # SimpleMaterial
            factor = getattr(mat, "diffuse", None)
            image = getattr(mat, "image", None)
        base = np.ones(3, np.float32) if factor is None else _unit_linear(factor)[..., :3]
        part["face_color"] = np.tile(base.reshape(1, 3), (n_t, 1))
        emissive = getattr(mat, "emissiveFactor", None)
        if emissive is not None and np.any(np.asarray(emissive) > 0):
            part["face_emission"] = np.tile(np.asarray(emissive, np.float32)[:3], (n_t, 1))
        colors = visual.vertex_attributes.get("color") if visual.vertex_attributes else None
        if colors is not None and len(colors) == len(v):
            part["vertex_color"] = _unit_linear(colors)
        uv = None if visual.uv is None else np.asarray(visual.uv, dtype=np.float32)
        if image is not None and uv is not None and len(uv) == len(v):
            rgb = np.asarray(image.convert("RGB"), dtype=np.float32) / 255.0
            part["textures"] = [srgb_to_linear(rgb)]
            part["uv"] = uv[:, :2][f]
    return part


def _unit_linear(colors) -> np.ndarray:
    """Colour arrays as floats in [0, 1] (integer types scaled by their maximum)."""
    c = np.asarray(colors)
    if np.issubdtype(c.dtype, np.integer):
        c = c.astype(np.float32) / np.float32(np.iinfo(c.dtype).max)
    return np.clip(np.atleast_2d(c.astype(np.float32))[:, :3], 0.0, 1.0)


def _unit_srgb(colors) -> np.ndarray:
    return srgb_to_linear(_unit_linear(colors))


def _concatenate(pieces: list[dict], name: str) -> TriangleMesh:
    offsets = np.cumsum([0] + [len(p["vertices"]) for p in pieces])
    n_tris = [len(p["triangles"]) for p in pieces]
    vertices = np.concatenate([p["vertices"] for p in pieces])
    triangles = np.concatenate([p["triangles"] + o for p, o in zip(pieces, offsets, strict=False)])
    face_color = np.concatenate([p["face_color"] for p in pieces])
    vertex_color = None
    if any(p["vertex_color"] is not None for p in pieces):
        vertex_color = np.concatenate(
            [
                p["vertex_color"]
                if p["vertex_color"] is not None
                else np.ones((len(p["vertices"]), 3), np.float32)
                for p in pieces
            ]
        )
    face_emission = None
    if any(p["face_emission"] is not None for p in pieces):
        face_emission = np.concatenate(
            [
                p["face_emission"] if p["face_emission"] is not None else np.zeros((n, 3))
                for p, n in zip(pieces, n_tris, strict=True)
            ]
        )
    uv = face_texture = None
    textures: list[np.ndarray] = []
    if any(p["textures"] for p in pieces):
        uvs, fts = [], []
        for p, n in zip(pieces, n_tris, strict=True):
            if p["textures"]:
                uvs.append(p["uv"])
                fts.append(np.full(n, len(textures), dtype=np.int32))
                textures.extend(p["textures"])
            else:
                uvs.append(np.zeros((n, 3, 2), np.float32))
                fts.append(np.full(n, -1, dtype=np.int32))
        uv, face_texture = np.concatenate(uvs), np.concatenate(fts)
    return TriangleMesh(
        vertices=vertices,
        triangles=triangles,
        face_color=face_color,
        vertex_color=vertex_color,
        uv=uv,
        face_texture=face_texture,
        textures=tuple(textures),
        face_emission=face_emission,
        name=name,
    )
