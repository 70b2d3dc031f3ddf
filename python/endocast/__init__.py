"""endocast: the braincase cavity (endocast) of a skull CT as a closed surface, and its volume.

    >>> import endocast
    >>> skull = endocast.phantom("human", spacing=2.0)
    >>> r = endocast.extract(skull.array, spacing=skull.spacing, origin=skull.origin)
    >>> abs(r.ecv_ml / skull.true_ecv_ml - 1) < 0.02
    True

Arrays are in (z, y, x) order, as SimpleITK's GetArrayFromImage and nibabel (transposed) give them;
spacing and origin are (x, y, z) in mm; meshes are in world mm (LPS), as the CLI writes them.
"""
import os

try:
    import numpy as _np
except ImportError:  # a python3 other than Debian's (e.g. pyenv): take Debian's numpy
    import sys as _sys
    _sys.path.append("/usr/lib/python3/dist-packages")
    import numpy as _np

from . import _endocast
from .errors import Error, InputError, NoResultError, OutOfMemoryError, ParameterError

__version__ = _endocast.__version__
__all__ = ["extract", "read_volume", "phantom", "read_mesh", "inspect", "compare", "simplify", "Mesh",
           "Volume", "Result", "RunWarning", "Error", "InputError", "ParameterError", "NoResultError", "OutOfMemoryError"]


class Mesh:
    """A triangle mesh: vertices (N, 3) float64 in world mm, faces (M, 3) uint32, outward."""

    def __init__(self, vertices, faces):
        self.vertices = _np.asarray(vertices, dtype=_np.float64)
        self.faces = _np.asarray(faces, dtype=_np.uint32)

    def write(self, path):
        """Writes .stl (binary), .ply, .obj or .off, atomically."""
        _endocast.write_mesh(self.vertices, self.faces, os.fspath(path))

    def __repr__(self):
        return f"Mesh({len(self.vertices)} vertices, {len(self.faces)} faces)"


class Volume:
    """A CT: array (z, y, x), spacing and origin (x, y, z) in mm, direction 3 x 3 (columns: the axes)."""

    def __init__(self, array, spacing, origin=(0.0, 0.0, 0.0), direction=None, **info):
        self.array = array
        self.spacing = tuple(float(s) for s in spacing)
        self.origin = tuple(float(o) for o in origin)
        self.direction = _np.eye(3) if direction is None else _np.asarray(direction, dtype=float).reshape(3, 3)
        self.__dict__.update(info)

    def __repr__(self):
        return f"Volume(shape {self.array.shape} (z, y, x), spacing {self.spacing} mm)"


class RunWarning(str):
    """A warning of a run (its result stands, but look): the message, with .code (a stable
    identifier such as "bone_contact_low" or "possible_leak") and .values (the numbers it is about)."""

    def __new__(cls, message, code, values):
        w = super().__new__(cls, message)
        w.code, w.values = code, dict(values)
        return w


class Result:
    """What extract() returns: ecv_ml, mesh, mask (uint8 (z, y, x), 1 = endocast), report (the
    CLI's report.json as a dict) and warnings (a list of RunWarning: a str with .code and .values)."""

    def __init__(self, d):
        self.ecv_ml = d["ecv_ml"]
        self.mesh = Mesh(d["mesh"]["vertices"], d["mesh"]["faces"])
        self.mask = d["mask"]
        self.report = d["report"]
        self.warnings = [RunWarning(w["message"], w["code"], w["values"]) for w in d["warnings"]]

    def __repr__(self):
        return f"Result(ecv_ml={self.ecv_ml:.3f}, {self.mesh!r}, {len(self.warnings)} warnings)"


def _paths(source):
    paths = [os.fspath(p) for p in source] if isinstance(source, (list, tuple)) else [os.fspath(source)]
    for p in paths:  # a slice pattern (%, *) or a DICOM folder is the library's to resolve
        if not any(c in p for c in "%*?") and not os.path.exists(p):
            raise FileNotFoundError(2, f"{p}: no such file or directory", p)
    return paths


def _mesh(m):
    if isinstance(m, (str, os.PathLike)):
        return read_mesh(m)
    return m


def extract(source, *, spacing=None, origin=None, direction=None, progress=None, **options):
    """Extracts the endocast of a CT, as `endocast extract` does.

    source: a path (NRRD, NIfTI, MetaImage, a DICOM folder, a TIFF stack), a list of paths, a
    numpy array (z, y, x) with spacing=(sx, sy, sz) mm (origin, direction optional), or a Volume.
    options: the CLI's long options with '_' for '-', in the CLI's units: iso (scan units; default
    automatic), surface ("iso" or "half-max"), crop (x0, y0, z0, x1, y1, z1 voxels), downsample,
    refine, refine_slab, max_memory_mb, void_radius_mm, thin_bone, seed_mode, seed_scale,
    seed_point (x, y, z mm), cut_planes, opening_radius_mm, keep_openings, series,
    series_description, slice_spacing, raw_size, raw_type, raw_header, raw_big_endian,
    check_all_faces; for raw and TIFF paths, spacing and origin.
    progress: called as progress(event, text), event "stage" or "info".

    The work runs without the GIL; Ctrl-C stops it at the next stage (KeyboardInterrupt).
    Raises FileNotFoundError, InputError, ParameterError (a ValueError), NoResultError,
    OutOfMemoryError, TypeError (an array of another dtype than numbers).
    """
    if isinstance(source, Volume):
        spacing, origin, direction, source = source.spacing, source.origin, source.direction, source.array
    if isinstance(source, _np.ndarray):
        geometry = {"spacing": spacing, "origin": origin, "direction": direction}
        return Result(_endocast.extract_array(source, geometry, options, progress))
    if direction is not None:
        raise ParameterError("direction: a path's geometry is its own")
    options.update(spacing=spacing, origin=origin)
    return Result(_endocast.extract_path(_paths(source), options, progress))


def read_volume(source, **options):
    """Reads a CT as extract() does (the same options for DICOM series and raw data): a Volume
    whose array is float32 (z, y, x) in the scan's units."""
    d = _endocast.read_volume(_paths(source), options)
    return Volume(d.pop("array"), d.pop("spacing"), d.pop("origin"), d.pop("direction"), **d)


def phantom(preset="human", *, spacing=0.0, seed=1, noise=True):
    """A generated skull CT with its true ECV: preset "human", "dry", "macaque" or "mouse";
    spacing in mm (0: the preset's). A Volume with true_ecv_ml and suggested_iso."""
    d = _endocast.phantom(preset, float(spacing), int(seed), bool(noise))
    return Volume(d.pop("array"), d.pop("spacing"), d.pop("origin"), d.pop("direction"), **d)


def read_mesh(path):
    """Reads .stl, .ply, .obj or .off into a Mesh (world mm)."""
    d = _endocast.read_mesh(os.fspath(_paths(path)[0]))
    return Mesh(d["vertices"], d["faces"])


def inspect(mesh):
    """The checks of `endocast inspect`: closed_manifold, genus, components, defects' counts,
    self_intersections, volume_ml, area_mm2. mesh: a Mesh or a path."""
    m = _mesh(mesh)
    return _endocast.inspect(m.vertices, m.faces)


def compare(a, b, *, align=True):
    """Surface distances between meshes a and b (mm) after rigid alignment of a onto b (align):
    a_to_b and b_to_a (mean, rms, median, p95, max, samples), hausdorff."""
    ma, mb = _mesh(a), _mesh(b)
    return _endocast.compare(ma.vertices, ma.faces, mb.vertices, mb.faces, bool(align))


def simplify(mesh, *, faces=0, ratio=0.0, max_error_mm=0.35):
    """Quadric simplification to `faces` faces or a `ratio` of them, keeping a closed 2-manifold
    without self-intersections within max_error_mm of the input. Returns (Mesh, info)."""
    m = _mesh(mesh)
    d = _endocast.simplify(m.vertices, m.faces, int(faces), float(ratio), float(max_error_mm))
    return Mesh(d.pop("vertices"), d.pop("faces")), d
