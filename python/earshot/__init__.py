"""earshot: CPU-only audio propagation (rays through geometry with per-band
materials, image sources, HRTF), from Python with numpy.

    import earshot
    scene = earshot.Scene("room.gltf", material_map="materials_map.json")
    r = scene.ir(source=(2, 3.5, 1.5), listener=(7, 3.5, 1.5), receiver="omni")
    r.samples          # float32 numpy array, shape (channels, frames)
    r.sample_rate, r.time_ms, r.params, r.stats

    rs = scene.ir_batch([(src, lis), ...], receiver="omni", seed=1)   # pair i: seed 1 + i, all cores
    earshot.analysis.analyze(r.samples, r.sample_rate)["T30"]          # ISO 3382-1 per band
    earshot.render("scene.json")                                       # a scene file to binaural audio

Every IR equals what `earshot ir` writes for the same inputs and seed
(bit-identical, whatever the thread count). Errors are Python exceptions
carrying the engine's message: ValueError (bad values, malformed files),
TypeError (wrong types), FileNotFoundError, OSError.

Datasets at scale: `python3 -m earshot dataset SPEC.json -o DIR` (see
earshot.dataset).
"""
import json as _json
import math as _math
import os as _os

import numpy as _np

from . import _earshot
from . import analysis  # noqa: F401  (earshot.analysis)
from .analysis import _json_text

__version__ = _earshot.__version__
BANDS_HZ = tuple(_earshot.bands_hz)
RECEIVERS = ("omni", "binaural")
QUALITIES = ("draft", "balanced", "high", "reference")
TRACE_MODES = ("per-source", "shared", "auto")

__all__ = ["Scene", "IR", "Render", "render", "analysis", "dataset", "BANDS_HZ", "RECEIVERS", "QUALITIES",
           "TRACE_MODES", "set_memory_limit", "memory_limit"]


def __getattr__(name):
    """earshot.dataset on first use (PEP 562), so that `import earshot`
    alone gives `earshot.dataset.make/load` as docs/python.md shows them,
    without loading the dataset module for every import."""
    if name == "dataset":
        import importlib
        return importlib.import_module(".dataset", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | {"dataset"})  # for completion, before its first use

_MAX_JSON_FILE_BYTES = 64 << 20


def _vec3(name, value):
    """A position or direction: three finite real numbers."""
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{name}: expected three numbers (x, y, z), got a string")
    try:
        a = _np.asarray(value)
    except Exception as e:  # ragged input and the like
        raise TypeError(f"{name}: expected three numbers (x, y, z)") from e
    if a.dtype.kind not in "fiu" or a.dtype == _np.bool_:
        raise TypeError(f"{name}: expected three numbers (x, y, z), got dtype {a.dtype}")
    if a.shape != (3,):
        raise ValueError(f"{name}: expected three numbers (x, y, z), got shape {a.shape}")
    a = a.astype(_np.float64)
    if not _np.all(_np.isfinite(a)):
        raise ValueError(f"{name}: coordinates must be finite, got {a.tolist()}")
    return tuple(float(x) for x in a)


def _path(value):
    if isinstance(value, _os.PathLike):
        return _os.fspath(value)
    if isinstance(value, str):
        return value
    return None


def _optional_uint(name, value):
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, _np.integer)):
        raise TypeError(f"{name}: expected a whole number, got {type(value).__name__}")
    if value < 0:
        raise ValueError(f"{name}: expected a whole number >= 0, got {value}")
    if value >= 2**32:
        raise ValueError(f"{name}: {value} is too large")
    return int(value)


def _number(name, value, allow_none=False):
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, _np.integer, _np.floating)):
        raise TypeError(f"{name}: expected a number, got {type(value).__name__}")
    v = float(value)
    if not _math.isfinite(v):
        raise ValueError(f"{name}: expected a finite number, got {v}")
    return v


def _air(value):
    if value is None or value is False or value == "off":
        return "off"
    if isinstance(value, str):
        return value
    t = _np.asarray(value, dtype=float)
    if t.shape != (2,):
        raise ValueError("air: expected 'off', 'TEMP_C,HUMIDITY_PCT' or (temperature_c, humidity_percent)")
    return f"{t[0]!r},{t[1]!r}"


def _read_json_file(path, what):
    try:
        size = _os.path.getsize(path)
    except OSError as e:
        raise FileNotFoundError(f"{path}: cannot read the {what}: {e.strerror}") from None
    if size > _MAX_JSON_FILE_BYTES:
        raise ValueError(f"{path}: the {what} is over {_MAX_JSON_FILE_BYTES >> 20} MB")
    try:
        with open(path, "rb") as f:
            return _json.loads(f.read())
    except (ValueError, RecursionError) as e:
        raise ValueError(f"{path}: the {what} is not valid JSON ({type(e).__name__})") from None


def _materials_args(materials):
    """(path, json text) for the engine from a path, a dict or None."""
    if materials is None:
        return None, None
    p = _path(materials)
    if p is not None:
        return p, None
    if isinstance(materials, dict):
        if "materials" not in materials:  # a bare {name: material} object
            materials = {"bands_hz": list(BANDS_HZ), "materials": materials}
        return None, _json_text(materials, "materials")
    raise TypeError("materials: expected a path, a dict or None")


_IR_ARGS = ("receiver", "forward", "up", "quality", "rays", "bounces", "ism_order", "bin_ms", "tail_probes",
            "sample_rate", "length", "air", "hrtf", "receiver_radius", "converge", "flutter_cones", "trace", "bands")


class IR:
    """One impulse response.

    samples: float32 array (channels, frames): omni 1 channel; binaural 2
    (left, right). sample_rate: Hz. time_ms: time of each stage (direct,
    early_reflections, trace, tail, synthesis, pipeline). params: everything
    that made it (positions, receiver, quality, rays, bounces, seed, ...).
    stats: what the engine reports about it (as `earshot ir --json`: direct
    path, rays traced and escaped, traced decay per band, tail, ...).
    warnings: e.g. a position outside the room's closed volume.
    """

    __slots__ = ("samples", "sample_rate", "time_ms", "params", "stats", "warnings")

    def __init__(self, raw, source, listener, kwargs):
        report = _json.loads(raw["report"])
        self.samples = raw["samples"]
        self.sample_rate = float(raw["sample_rate"])
        self.time_ms = report.pop("time_ms")
        settings = report.pop("settings")
        params = {"source": list(source), "listener": list(listener), "receiver": raw["receiver"],
                  "quality": raw["quality"], "trace": raw["trace"], "bands": kwargs["bands"]}
        params.update(settings)
        if raw["receiver"] == "binaural":
            params["forward"] = list(kwargs["forward"])
            params["up"] = list(kwargs["up"])
            params["hrtf"] = kwargs["hrtf"] or "default"
        self.params = params
        self.stats = report
        self.warnings = list(raw["warnings"])

    @property
    def channels(self):
        return self.samples.shape[0]

    def __repr__(self):
        return (f"earshot.IR({self.params['receiver']}, {self.samples.shape[0]} ch x {self.samples.shape[1]} "
                f"frames at {self.sample_rate:g} Hz, seed {self.params['seed']})")


class Scene:
    """A scene: geometry (glTF 2.0, or arrays) with acoustic materials, loaded
    once; then any number of IRs, from any number of threads.

    Scene(geometry=None, materials=None, material_map=None): geometry a
    .gltf/.glb path (None: free field); materials a materials file (path) or
    dict in its format (default: the built-in set); material_map a path or a
    dict {glTF material name: acoustic material name}. File references inside
    a glTF stay inside its folder unless allow_outside_paths; max_memory
    (bytes) caps what the file may make the engine allocate (default 1 GiB).
    """

    def __init__(self, geometry=None, materials=None, material_map=None, *, allow_outside_paths=False,
                 max_memory=None):
        g = None
        if geometry is not None:
            g = _path(geometry)
            if g is None:
                raise TypeError("geometry: expected a path to a .gltf/.glb file or None")
        mpath, mtext = _materials_args(materials)
        map_path, map_dict = None, {}
        if material_map is not None:
            map_path = _path(material_map)
            if map_path is None:
                if not isinstance(material_map, dict) or not all(
                        isinstance(k, str) and isinstance(v, str) for k, v in material_map.items()):
                    raise TypeError("material_map: expected a path or a dict {str: str}")
                map_dict = dict(material_map)
        mm = 0 if max_memory is None else _optional_uint_big("max_memory", max_memory)
        self._s = _earshot._Scene.load(g, mpath, mtext, map_path, map_dict, bool(allow_outside_paths), mm)
        self._name = g or "free field"

    @classmethod
    def from_arrays(cls, vertices, triangles, material_ids, materials, *, material_library=None):
        """A scene from arrays: vertices (N, 3) metres; triangles (M, 3) vertex
        indices (integers); material_ids (M,) integers, each an index into
        `materials`: a list of material names (looked up in
        material_library, a path or dict, default the built-in set), a dict
        {name: material} (or a whole materials-file dict), or a materials
        file; index k is the k-th material listed."""
        v = _np.asarray(vertices)
        if v.size == 0:
            v = v.astype(_np.float64).reshape(0, 3)
        if v.dtype.kind not in "fiu" or v.dtype == _np.bool_:
            raise TypeError(f"vertices: expected real numbers, got dtype {v.dtype}")
        t = _np.asarray(triangles)
        if t.size == 0:  # [] is float64, of shape (0,), to numpy
            t = t.astype(_np.int64).reshape(0, 3)
        if t.dtype.kind not in "iu":
            raise TypeError(f"triangles: expected integer vertex indices, got dtype {t.dtype}")
        ids = _np.asarray(material_ids)
        if ids.size == 0:
            ids = ids.astype(_np.int64)
        if ids.dtype.kind not in "iu":
            raise TypeError(f"material_ids: expected integers, got dtype {ids.dtype}")
        if t.size and t.max() > _np.iinfo(_np.int64).max:
            raise ValueError("triangles: index too large")
        if isinstance(materials, (list, tuple)):
            names = list(materials)
            if not all(isinstance(n, str) for n in names):
                raise TypeError("materials: a list must hold material names (str)")
            mpath, mtext = _materials_args(material_library)
        else:
            if material_library is not None:
                raise ValueError("material_library: only with a list of material names")
            p = _path(materials)
            if p is not None:
                doc = _read_json_file(p, "materials file")
            elif isinstance(materials, dict):
                doc = materials if "materials" in materials else {"materials": materials}
            else:
                raise TypeError("materials: expected a list of names, a dict or a materials file")
            if not isinstance(doc, dict) or not isinstance(doc.get("materials"), dict):
                raise ValueError("materials: expected an object with a 'materials' object")
            names = list(doc["materials"].keys())
            mpath, mtext = _materials_args(materials)
        self = cls.__new__(cls)
        self._s = _earshot._Scene.from_arrays(v.astype(_np.float64, copy=False).reshape(v.shape),
                                              t.astype(_np.int64), ids.astype(_np.int64), names, mpath, mtext)
        self._name = "arrays"
        return self

    @property
    def triangle_count(self):
        return self._s.triangle_count

    @property
    def warnings(self):
        """The loader's warnings (unmapped materials, skipped primitives, ...)."""
        return list(self._s.warnings)

    @property
    def closed(self):
        """True when the geometry is a closed (watertight) volume."""
        return self._s.closed

    @property
    def bounds(self):
        """(min corner, max corner) of the geometry, metres."""
        lo, hi = self._s.bounds
        return tuple(lo), tuple(hi)

    def contains(self, point):
        """True inside the closed volume, False outside, None when the
        geometry bounds no volume (open mesh, free field)."""
        e = self._s.enclosure(_vec3("point", point))
        return None if e == "open" else e == "inside"

    def arrays(self):
        """(vertices (N, 3) float64, triangles (M, 3) int64) as loaded."""
        return self._s.arrays()

    def distance_to_surface(self, point):
        """Distance (m) from `point` to the nearest triangle (inf without
        geometry)."""
        v, t = self._s.arrays()
        return float(_point_mesh_distance(_np.asarray(_vec3("point", point)), v, t))

    @property
    def material_names(self):
        return list(self._s.material_names)

    def _kwargs(self, receiver="binaural", order=None, forward=(0.0, 0.0, -1.0), up=(0.0, 1.0, 0.0),
                quality="balanced", rays=None, bounces=None, ism_order=None, bin_ms=None, tail_probes=None,
                sample_rate=48000.0, length=None, air="20,50", hrtf=None, receiver_radius=0.0, converge=0.0,
                flutter_cones=True, trace="per-source", bands="octave", **unknown):
        if unknown:  # named as the caller's option, not as this helper's argument
            import inspect
            known = [n for n in inspect.signature(Scene._kwargs).parameters if n not in ("self", "unknown")]
            raise TypeError(f"unknown option(s) {sorted(unknown)}; the options are {known}")
        if not isinstance(receiver, str):
            raise TypeError("receiver: expected 'omni', 'binaural' or 'ambisonic'")
        if order is not None and receiver != "ambisonic":
            raise ValueError("order: applies only to receiver='ambisonic'")
        if receiver == "ambisonic":
            order = 1 if order is None else order
            if isinstance(order, bool) or not isinstance(order, (int, _np.integer)):
                raise TypeError(f"order: expected a whole number 1 .. 3, got {type(order).__name__}")
        else:
            order = 0
        if not isinstance(quality, str):
            raise TypeError("quality: expected one of " + ", ".join(QUALITIES))
        if not isinstance(trace, str):
            raise TypeError("trace: expected one of " + ", ".join(TRACE_MODES))
        if not isinstance(bands, str):
            raise TypeError("bands: expected 'octave' or 'third-octave'")
        h = ""
        if hrtf is not None:
            h = _path(hrtf)
            if h is None:
                raise TypeError("hrtf: expected a path to a SOFA file or None")
        return dict(receiver=receiver, order=int(order), forward=_vec3("forward", forward), up=_vec3("up", up),
                    quality=quality,
                    rays=_optional_uint("rays", rays), bounces=_optional_uint("bounces", bounces),
                    ism_order=_optional_uint("ism_order", ism_order),
                    bin_ms=_number("bin_ms", bin_ms, allow_none=True),
                    tail_probes=_optional_uint("tail_probes", tail_probes),
                    sample_rate=_number("sample_rate", sample_rate), length=_number("length", length, True),
                    air=_air(air), hrtf=h, receiver_radius=_number("receiver_radius", receiver_radius),
                    converge=_number("converge", converge), flutter_cones=bool(flutter_cones), trace=trace,
                    bands=bands)

    def ir(self, source, listener, *, seed=1, threads=0, **options):
        """The IR from `source` to `listener` (metres). Options (as `earshot
        ir`): receiver 'omni' | 'binaural' (default, HRTF; forward, up: the
        listener's orientation, default (0,0,-1), (0,1,0); hrtf: a SOFA file,
        default the shipped set) | 'ambisonic' (order 1-3, default 1: AmbiX,
        ACN order, SN3D, (order+1)^2 channels in the listener's frame, x
        forward, y left, z up; W is the omni IR), quality 'draft' | 'balanced' | 'high' |
        'reference' and any of rays, bounces, ism_order, bin_ms, tail_probes
        over it, sample_rate (Hz), length (s, default from the decay), air
        ('off', 'T,H' or (T, H)), receiver_radius, converge (dB),
        flutter_cones, trace ('per-source', the default: rays from the
        source; 'shared': rays from the listener, by reciprocity the same
        energies, see ir_batch; 'auto': per source for one pair); bands
        ('octave', the default, or 'third-octave': 21 bands 100 Hz - 10 kHz
        from three shifted passes, ~3x the time, per source only; stats
        ['third_octave'] has each band's traced decay); seed; threads (0:
        all cores). The GIL is released while it computes."""
        kw = self._kwargs(**options)
        src, lis = _vec3("source", source), _vec3("listener", listener)
        raw = self._s.ir(src, lis, seed=_seed(seed), threads=_threads(threads), **_engine_args(kw))
        return IR(raw, src, lis, kw)

    def ir_batch(self, pairs, *, seed=1, threads=0, **options):
        """IRs of many (source, listener) pairs with one set of options: pair
        i gets seed + i, and equals ir(source_i, listener_i, seed=seed + i).
        Runs whole IRs in parallel on `threads` (0: all cores) with the GIL
        released; nothing is loaded again. Returns a list of IR. (Each IR is
        kept: for very many, call it on chunks, or use earshot.dataset.)

        trace='shared': the pairs with the same listener are traced together,
        one trace from the listener on all threads for all their sources
        (far cheaper than a trace each for many sources: docs/performance.md),
        with seed + the index of the group's first pair; pair k then equals
        ir(source_k, listener, seed=that seed, trace='shared'). trace='auto':
        shared for listeners with 3 pairs or more, the others per source.
        Each IR's params['trace'] says which it got.

        IRs made side by side share the memory limit (set_memory_limit):
        with T at once each is checked against the limit / T; one refused
        by its share alone is made again afterwards, alone, under the whole
        limit (the same bits; its warnings say so)."""
        kw = self._kwargs(**options)
        if isinstance(pairs, _np.ndarray):
            if pairs.ndim != 3 or pairs.shape[1:] != (2, 3):
                raise ValueError(f"pairs: expected shape (K, 2, 3), got {pairs.shape}")
        ps = []
        for i, p in enumerate(pairs):
            try:
                s, l = p
            except (TypeError, ValueError):
                raise ValueError(f"pairs[{i}]: expected (source, listener)") from None
            ps.append((_vec3(f"pairs[{i}] source", s), _vec3(f"pairs[{i}] listener", l)))
        s0 = _seed(seed)
        if ps and s0 + len(ps) - 1 >= 2**64:
            raise ValueError("seed: seed + len(pairs) - 1 must stay below 2^64")
        raws = self._s.ir_batch(ps, seed=s0, threads=_threads(threads), **_engine_args(kw))
        out = []
        for i, (raw, (s, l)) in enumerate(zip(raws, ps)):
            out.append(IR(raw, s, l, kw))
        return out

    def __repr__(self):
        return f"earshot.Scene({self._name!r}, {self.triangle_count} triangles)"


def _point_mesh_distance(p, vertices, triangles):
    """Exact distance from p to a triangle mesh (closest point per triangle,
    Ericson, Real-Time Collision Detection 5.1.5), vectorised over triangles."""
    if len(triangles) == 0:
        return _math.inf
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = _np.einsum("ij,ij->i", ab, ap), _np.einsum("ij,ij->i", ac, ap)
    bp, cp = p - b, p - c
    d3, d4 = _np.einsum("ij,ij->i", ab, bp), _np.einsum("ij,ij->i", ac, bp)
    d5, d6 = _np.einsum("ij,ij->i", ab, cp), _np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with _np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v = _np.where(denom != 0, vb / denom, 0.0)
        w = _np.where(denom != 0, vc / denom, 0.0)
        q = a + ab * v[:, None] + ac * w[:, None]  # inside the face
        # Edges and vertices, in the order of the regions' tests (last wins
        # in reverse: apply the face first, then overwrite).
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        m = (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)
        q[m] = (b + (c - b) * t_bc[:, None])[m]
        t_ac = d2 / (d2 - d6)
        m = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        q[m] = (a + ac * t_ac[:, None])[m]
        m = (d6 >= 0) & (d5 <= d6)
        q[m] = c[m]
        t_ab = d1 / (d1 - d3)
        m = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        q[m] = (a + ab * t_ab[:, None])[m]
        m = (d3 >= 0) & (d4 <= d3)
        q[m] = b[m]
        m = (d1 <= 0) & (d2 <= 0)
        q[m] = a[m]
    return float(_np.sqrt(_np.nanmin(_np.einsum("ij,ij->i", q - p, q - p))))


def _engine_args(kw):
    return dict(receiver=kw["receiver"], forward=kw["forward"], up=kw["up"], quality=kw["quality"],
                rays=kw["rays"], bounces=kw["bounces"], ismOrder=kw["ism_order"], binMs=kw["bin_ms"],
                tailProbes=kw["tail_probes"], sampleRate=kw["sample_rate"], length=kw["length"], air=kw["air"],
                hrtf=kw["hrtf"], receiverRadius=kw["receiver_radius"], converge=kw["converge"],
                flutterCones=kw["flutter_cones"], order=kw["order"], trace=kw["trace"], bands=kw["bands"])


def _seed(seed):
    if isinstance(seed, bool) or not isinstance(seed, (int, _np.integer)):
        raise TypeError(f"seed: expected a whole number, got {type(seed).__name__}")
    if not 0 <= int(seed) < 2**64:
        raise ValueError(f"seed: expected 0 <= seed < 2^64, got {seed}")
    return int(seed)


def _threads(threads):
    t = _optional_uint("threads", threads)
    if t > 256:
        raise ValueError("threads: expected 0 .. 256")
    return t


def _optional_uint_big(name, value):
    if isinstance(value, bool) or not isinstance(value, (int, _np.integer)):
        raise TypeError(f"{name}: expected a whole number of bytes")
    if not 0 < int(value) < 2**63:
        raise ValueError(f"{name}: expected a positive number of bytes")
    return int(value)


def set_memory_limit(bytes_):
    """The process's memory limit in bytes (default 1 GiB; the CLI's
    --max-memory): what a ray count (a trace's state, ~150 bytes a ray), an
    IR's length and channels (its synthesis) or a scene's render may make
    the engine allocate, estimated before allocating and refused past it
    (ValueError naming the limit). None or 0 sets the default back. A
    Scene's own max_memory caps its file's loading."""
    if bytes_ is None:
        bytes_ = 0
    if isinstance(bytes_, bool) or not isinstance(bytes_, (int, _np.integer)):
        raise TypeError("bytes: expected a whole number of bytes or None")
    if not 0 <= int(bytes_) < 2**63:
        raise ValueError("bytes: expected a positive number of bytes, or 0 or None for the default")
    _earshot._set_memory_limit(int(bytes_))


def memory_limit():
    """The process's memory limit in bytes (set_memory_limit)."""
    return int(_earshot._memory_limit())


class Render:
    """An offline render: samples float32 (2, frames) (left, right),
    sample_rate, and info (audio/wall/simulation seconds, simulations, peak,
    clipped, log, warnings)."""

    __slots__ = ("samples", "sample_rate", "info")

    def __init__(self, raw):
        self.samples = raw.pop("samples")
        self.sample_rate = float(raw.pop("sample_rate"))
        self.info = dict(raw)

    def __repr__(self):
        return f"earshot.Render({self.samples.shape[1] / self.sample_rate:.2f} s at {self.sample_rate:g} Hz)"


def render(scene, *, base_dir=None, quality=None, seed=None, threads=0, start=0.0, end=None, strict=False,
           allow_outside_paths=False):
    """Renders a scene (the format of `earshot render`, docs/scene-format.md)
    to binaural audio in memory. `scene`: a path to a scene file, a dict, or
    JSON text; files it names resolve against base_dir (default: the scene
    file's folder, or the current directory for a dict or text)."""
    if isinstance(scene, dict):
        text, name = _json_text(scene, "scene"), "scene"
        base = base_dir or _os.getcwd()
    elif _path(scene) is not None and (isinstance(scene, _os.PathLike) or not scene.lstrip().startswith("{")):
        p = _path(scene)
        if not _os.path.isfile(p):
            shown = p if len(p) <= 200 else p[:197] + "..."  # a long string that is neither a path nor JSON text
            raise FileNotFoundError(f"{shown}: no such scene file")
        if _os.path.getsize(p) > _MAX_JSON_FILE_BYTES:
            raise ValueError(f"{p}: the scene file is over {_MAX_JSON_FILE_BYTES >> 20} MB")
        with open(p, "rb") as f:
            text = f.read().decode("utf-8", errors="replace")
        name = p
        base = base_dir or _os.path.dirname(_os.path.abspath(p))
    elif isinstance(scene, str):
        text, name = scene, "scene"
        base = base_dir or _os.getcwd()
    else:
        raise TypeError("scene: expected a path, a dict or JSON text")
    if quality is not None and quality not in QUALITIES:
        raise ValueError("quality: expected one of " + ", ".join(QUALITIES))
    s = None if seed is None else _seed(seed)
    return Render(_earshot._render(text, _os.fspath(base), name, quality, s, _threads(threads),
                                   _number("start", start), _number("end", end, allow_none=True), bool(strict),
                                   bool(allow_outside_paths)))
