"""IR datasets at scale: a spec file in, sharded HDF5 (or WAV) IRs and a
manifest out, on one machine (a Dask LocalCluster) or a Dask cluster.

    python3 -m earshot dataset SPEC.json -o DIR [--workers N | --scheduler tcp://host:8786 | --in-process]
    earshot.dataset.make(spec, "DIR", workers=2)
    for id, samples, params in earshot.dataset.load("DIR"): ...

The spec (JSON; paths relative to the spec file's folder, and kept inside it
unless allow_outside_paths):

    {
      "rooms": [                                   # required, at least one
        {"geometry": "room.glb", "materials": "m.json", "material_map": "map.json"},
        {"generator": "shoebox", "rooms": 10,      # 10 rooms drawn from these distributions
         "size_m": {"x": [3, 12], "y": [3, 10], "z": [2.4, 4]},        # uniform ranges (default)
         "materials": {"walls": ["brick", "plaster"], "floor": ["carpet_thin", "wood_floor"],
                       "ceiling": ["acoustic_ceiling_tile", "plaster"]}}   # a choice per surface
        # or "absorption": [0.02, 0.5], "scattering": [0.05, 0.5]: random per-band materials
      ],
      "count": 1000,            # IRs (default 100)
      "seed": 1,                # default 1
      "receiver": "omni",       # omni | binaural (default omni)
      "quality": "balanced",    # draft | balanced | high | reference (default balanced)
      "sample_rate": 48000,     # default 48000
      "positions": {"wall_distance_m": 0.5,     # from every surface (default 0.5)
                    "min_separation_m": 1.0,    # source to listener (default 1.0)
                    "height_m": null},          # [lo, hi] above the room's floor, or null: anywhere
      "format": "hdf5",         # hdf5 | wav (default hdf5)
      "shard_size": 100,        # IRs per shard (default 100)
      "ir_options": {}          # any other option of Scene.ir (rays, bounces, length, air, ...; hrtf: a
                                # SOFA file relative to the spec's folder, like the rooms' files)
    }

IR i is made in room i mod R (R rooms after generators expand), with seed
seed + i and positions drawn from a generator seeded by (seed, i): the same
spec gives the same IRs whatever the number of workers. Shards are written
to a temporary name and renamed when complete, so a killed run resumes where
it stopped (`make` again on the same DIR) and never leaves a half-written
shard that looks complete; a shard that lost or cut an IR since is made
again. DIR/manifest.jsonl lists every IR's parameters and
its ISO 3382-1 metrics (per channel, per band: EDT, T20, T30, C50, C80, D50,
Ts), and DIR/spec.json the spec it was made from.
"""
import hashlib
import json
from array import array
import math
import os
import struct
import sys
import time

import numpy as np

import earshot
from earshot import analysis as _analysis

__all__ = ["make", "load", "read_spec", "resolve_spec", "DEFAULTS"]

DEFAULTS = {
    "count": 100, "seed": 1, "receiver": "omni", "quality": "balanced", "sample_rate": 48000,
    "positions": {"wall_distance_m": 0.5, "min_separation_m": 1.0, "height_m": None},
    "format": "hdf5", "shard_size": 100, "ir_options": {},
}
_SPEC_KEYS = {"rooms", "description"} | set(DEFAULTS)
_FILE_ROOM_KEYS = {"geometry", "materials", "material_map", "name"}
_GEN_KEYS = {"generator", "rooms", "size_m", "materials", "absorption", "scattering", "name"}
_MAX_COUNT = 10_000_000
_MAX_SPEC_BYTES = 16 << 20  # a spec file, and the spec.json make writes beside its shards
_MAX_ROOMS = 100_000
_PLACEMENT_ATTEMPTS = 2000
_FORMAT_VERSION = 1


class SpecError(ValueError):
    """The spec is invalid (the message names the field)."""


class _Damaged(ValueError):
    """What this module found wrong in a dataset's file (its message says
    what, never the file's contents); other errors are named by their type."""


def _why(e):
    return str(e) if isinstance(e, _Damaged) else type(e).__name__


def _check_size(nbytes, what):
    """A file's claim of `nbytes` to read, against the memory limit, first."""
    if nbytes > earshot.memory_limit():
        raise _Damaged(f"{what}, over the memory limit of {earshot.memory_limit() / 2**20:.1f} MiB "
                       "(earshot.set_memory_limit)")


def _short(v, n=40):
    """A spec value for a message: its repr (one line: newlines escaped),
    cut to n characters."""
    t = repr(v)
    return t if len(t) <= n else t[:n - 3] + "..."


# ---------------------------------------------------------------- the spec

def read_spec(path, *, allow_outside_paths=False):
    """Reads and resolves a spec file (see resolve_spec)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{path}: no such spec file")
    if os.path.getsize(path) > _MAX_SPEC_BYTES:
        raise SpecError(f"{path}: the spec is over 16 MB")
    try:
        with open(path, "rb") as f:
            spec = json.loads(f.read())
    except (ValueError, RecursionError) as e:
        raise SpecError(f"{path}: not valid JSON ({type(e).__name__})") from None
    return resolve_spec(spec, os.path.dirname(os.path.abspath(path)), allow_outside_paths=allow_outside_paths,
                        name=path)


def _inside(base, rel, field, allow_outside):
    if not isinstance(rel, str) or not rel or "\0" in rel:
        raise SpecError(f"{field}: expected a file name")
    p = os.path.realpath(os.path.join(base, rel))
    root = os.path.realpath(base)
    if not allow_outside and os.path.commonpath([p, root]) != root:
        raise SpecError(f"{field}: {_short(rel, 200)} leads outside the spec's folder (allow_outside_paths to permit)")
    if not os.path.isfile(p):
        raise SpecError(f"{field}: {_short(rel, 200)} is not a file")
    return p


def _range(v, field, lo=0.0, hi=math.inf):
    if (not isinstance(v, (list, tuple)) or len(v) != 2
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)):
        raise SpecError(f"{field}: expected [min, max]")
    a, b = float(v[0]), float(v[1])
    if not (math.isfinite(a) and math.isfinite(b) and lo <= a <= b <= hi):
        raise SpecError(f"{field}: expected {lo:g} <= min <= max <= {hi:g}, got {_short(list(v))}")
    return [a, b]


def resolve_spec(spec, base_dir, *, allow_outside_paths=False, name="spec"):
    """Checks a spec (dict), fills in the defaults and makes its paths
    absolute. Errors are SpecError (a ValueError) naming the field."""
    if not isinstance(spec, dict):
        raise SpecError(f"{name}: expected a JSON object")
    unknown = set(spec) - _SPEC_KEYS
    if unknown:
        raise SpecError(f"{name}: unknown key(s) {_short(sorted(unknown))}; expected {sorted(_SPEC_KEYS)}")
    out = json.loads(json.dumps(DEFAULTS))
    for k, v in spec.items():
        if k == "positions":
            if not isinstance(v, dict) or set(v) - set(DEFAULTS["positions"]):
                raise SpecError(f"positions: expected an object with {sorted(DEFAULTS['positions'])}")
            out["positions"].update(v)
        else:
            out[k] = v
    def whole(field, lo, hi):
        v = out[field]
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise SpecError(f"{field}: expected a whole number in [{lo}, {hi}], got {_short(v)}")
    whole("count", 1, _MAX_COUNT)
    whole("seed", 0, 2**63 - 1 - _MAX_COUNT)
    whole("shard_size", 1, 100_000)
    if out["receiver"] not in earshot.RECEIVERS:
        raise SpecError(f"receiver: expected one of {earshot.RECEIVERS}")
    if out["quality"] not in earshot.QUALITIES:
        raise SpecError(f"quality: expected one of {earshot.QUALITIES}")
    if out["format"] not in ("hdf5", "wav"):
        raise SpecError("format: expected 'hdf5' or 'wav'")
    sr = out["sample_rate"]
    if isinstance(sr, bool) or not isinstance(sr, (int, float)) or not 8000 <= sr <= 384000:
        raise SpecError("sample_rate: expected 8000 .. 384000")
    pos = out["positions"]
    for k in ("wall_distance_m", "min_separation_m"):
        v = pos[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (0 <= v < 1e3):
            raise SpecError(f"positions.{k}: expected metres >= 0")
    if pos["height_m"] is not None:
        pos["height_m"] = _range(pos["height_m"], "positions.height_m")
    if not isinstance(out["ir_options"], dict):
        raise SpecError("ir_options: expected an object")
    bad = set(out["ir_options"]) & {"receiver", "quality", "sample_rate", "seed", "threads"}
    if bad:
        raise SpecError(f"ir_options: {sorted(bad)} are set at the spec's top level")
    # A file the options name is the spec's as the rooms' files are: relative
    # to its folder and inside it (not relative to wherever a worker runs).
    out["ir_options"] = dict(out["ir_options"])
    if out["ir_options"].get("hrtf") is not None:
        out["ir_options"]["hrtf"] = _inside(base_dir, out["ir_options"]["hrtf"], "ir_options.hrtf",
                                            allow_outside_paths)
    rooms = out.get("rooms")
    if not isinstance(rooms, list) or not rooms:
        raise SpecError("rooms: expected a non-empty list")
    resolved, total = [], 0
    for i, r in enumerate(rooms):
        f = f"rooms[{i}]"
        if not isinstance(r, dict):
            raise SpecError(f"{f}: expected an object")
        if "generator" in r:
            unknown = set(r) - _GEN_KEYS
            if unknown:
                raise SpecError(f"{f}: unknown key(s) {_short(sorted(unknown))}")
            if r["generator"] != "shoebox":
                raise SpecError(f"{f}.generator: expected 'shoebox'")
            g = {"generator": "shoebox", "rooms": r.get("rooms", 1)}
            if isinstance(g["rooms"], bool) or not isinstance(g["rooms"], int) or not 1 <= g["rooms"] <= _MAX_ROOMS:
                raise SpecError(f"{f}.rooms: expected a whole number in [1, {_MAX_ROOMS}]")
            size = r.get("size_m", {"x": [3, 12], "y": [3, 10], "z": [2.4, 4]})
            if not isinstance(size, dict) or set(size) != {"x", "y", "z"}:
                raise SpecError(f"{f}.size_m: expected {{x: [min, max], y: [...], z: [...]}}")
            g["size_m"] = {a: _range(size[a], f"{f}.size_m.{a}", 0.5, 1000.0) for a in "xyz"}
            if "materials" in r and ("absorption" in r or "scattering" in r):
                raise SpecError(f"{f}: give either materials (names) or absorption/scattering ranges")
            if "absorption" in r or "scattering" in r:
                g["absorption"] = _range(r.get("absorption", [0.02, 0.5]), f"{f}.absorption", 0.0, 1.0)
                g["scattering"] = _range(r.get("scattering", [0.05, 0.5]), f"{f}.scattering", 0.0, 1.0)
            else:
                mats = r.get("materials", {"walls": ["brick", "plaster", "concrete", "gypsum_board"],
                                           "floor": ["wood_floor", "carpet_thin", "linoleum", "concrete"],
                                           "ceiling": ["plaster", "acoustic_ceiling_tile", "concrete"]})
                known = set(earshot.Scene().material_names)
                if not isinstance(mats, dict) or set(mats) != {"walls", "floor", "ceiling"}:
                    raise SpecError(f"{f}.materials: expected {{walls: [...], floor: [...], ceiling: [...]}}")
                for k, names in mats.items():
                    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
                        raise SpecError(f"{f}.materials.{k}: expected a non-empty list of material names")
                    for n in names:
                        if n not in known:
                            raise SpecError(f"{f}.materials.{k}: no built-in material named {_short(n)}")
                g["materials"] = mats
            g["name"] = str(r.get("name", f"shoebox{i}"))
            total += g["rooms"]
            resolved.append(g)
        else:
            unknown = set(r) - _FILE_ROOM_KEYS
            if unknown:
                raise SpecError(f"{f}: unknown key(s) {_short(sorted(unknown))} (a file room has geometry, materials, "
                                "material_map; a generated one has generator)")
            if "geometry" not in r:
                raise SpecError(f"{f}: expected geometry (a .gltf/.glb file) or a generator")
            g = {"geometry": _inside(base_dir, r["geometry"], f"{f}.geometry", allow_outside_paths)}
            for k in ("materials", "material_map"):
                if r.get(k) is not None:
                    g[k] = _inside(base_dir, r[k], f"{f}.{k}", allow_outside_paths)
            g["name"] = str(r.get("name", os.path.basename(r["geometry"])))
            total += 1
            resolved.append(g)
        if total > _MAX_ROOMS:
            raise SpecError(f"rooms: more than {_MAX_ROOMS} rooms")
    out["rooms"] = resolved
    out["allow_outside_paths"] = bool(allow_outside_paths)
    # Checked now rather than on every worker: the IR options.
    try:
        earshot.Scene()._kwargs(receiver=out["receiver"], quality=out["quality"], sample_rate=float(sr),
                                **out["ir_options"])
    except (TypeError, ValueError) as e:
        raise SpecError(f"ir_options: {e}") from None
    return out


def _spec_hash(spec):
    return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()


# ---------------------------------------------------------------- rooms

def _room_list(spec):
    """[(entry index, k)] for every concrete room, in order."""
    rooms = []
    for i, r in enumerate(spec["rooms"]):
        for k in range(r.get("rooms", 1) if "generator" in r else 1):
            rooms.append((i, k))
    return rooms


def _room_rng(spec, entry, k):
    return np.random.default_rng([spec["seed"], 0x5EED, entry, k])


def _box(size):
    x, y, z = size
    v = np.array([[0, 0, 0], [x, 0, 0], [x, y, 0], [0, y, 0], [0, 0, z], [x, 0, z], [x, y, z], [0, y, z]], float)
    # Normals into the room; material slots: 0 walls, 1 floor, 2 ceiling.
    t = np.array([[0, 3, 7], [0, 7, 4], [1, 5, 6], [1, 6, 2],      # x = 0, x = X
                  [0, 4, 5], [0, 5, 1], [3, 2, 6], [3, 6, 7],      # y = 0, y = Y
                  [0, 1, 2], [0, 2, 3], [4, 7, 6], [4, 6, 5]])     # floor, ceiling
    ids = np.array([0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 2, 2])
    return v, t, ids


def _room_description(spec, entry, k):
    """What defines concrete room (entry, k): everything needed to build it."""
    r = spec["rooms"][entry]
    if "generator" not in r:
        return {"name": r["name"], "geometry": r["geometry"], "materials": r.get("materials"),
                "material_map": r.get("material_map")}
    rng = _room_rng(spec, entry, k)
    size = [float(rng.uniform(*r["size_m"][a])) for a in "xyz"]
    d = {"name": f"{r['name']}-{k}", "generator": "shoebox", "size_m": size}
    if "materials" in r:
        d["materials"] = [str(rng.choice(r["materials"][s])) for s in ("walls", "floor", "ceiling")]
    else:
        mats = {}
        for s in ("walls", "floor", "ceiling"):
            mats[s] = {"absorption": [round(float(a), 6) for a in rng.uniform(*r["absorption"], 7)],
                       "scattering": [round(float(a), 6) for a in rng.uniform(*r["scattering"], 7)]}
        d["materials"] = mats
    return d


def _build_room(d, allow_outside):
    if "generator" not in d:
        return earshot.Scene(d["geometry"], materials=d["materials"], material_map=d["material_map"],
                             allow_outside_paths=allow_outside)
    v, t, ids = _box(d["size_m"])
    if isinstance(d["materials"], list):
        return earshot.Scene.from_arrays(v, t, ids, d["materials"])
    return earshot.Scene.from_arrays(v, t, ids, {s: d["materials"][s] for s in ("walls", "floor", "ceiling")})


# Each worker process keeps the scenes it has loaded.
_SCENES = {}


def _scene(d, allow_outside):
    key = json.dumps(d, sort_keys=True)
    s = _SCENES.get(key)
    if s is None:
        if len(_SCENES) >= 64:
            _SCENES.pop(next(iter(_SCENES)))
        s = _SCENES[key] = _build_room(d, allow_outside)
    return s


def _place(spec, scene, index, room_name):
    """Source and listener for IR `index`: inside the room, at least
    wall_distance_m from every surface, min_separation_m apart."""
    pos = spec["positions"]
    rng = np.random.default_rng([spec["seed"], index])
    lo, hi = (np.array(b) for b in scene.bounds)
    v, t = scene.arrays()
    w = pos["wall_distance_m"]
    zr = None
    if pos["height_m"] is not None:
        zr = (lo[2] + pos["height_m"][0], lo[2] + pos["height_m"][1])
    def one():
        for _ in range(_PLACEMENT_ATTEMPTS):
            p = rng.uniform(lo + w, np.maximum(hi - w, lo + w))
            if zr is not None:
                p[2] = rng.uniform(*zr)
            if scene.contains(p) is False:
                continue
            if w > 0 and earshot._point_mesh_distance(p, v, t) < w:
                continue
            return p
        raise ValueError(f"room {_short(room_name)}: no position {w} m from every surface found in "
                         f"{_PLACEMENT_ATTEMPTS} tries (wall_distance_m too large?)")
    for _ in range(_PLACEMENT_ATTEMPTS):
        s, l = one(), one()
        if np.linalg.norm(s - l) >= pos["min_separation_m"]:
            return [float(x) for x in s], [float(x) for x in l]
    raise ValueError(f"room {_short(room_name)}: no pair {pos['min_separation_m']} m apart found")


def _metrics(samples, rate):
    try:
        a = _analysis.analyze(samples, rate)
    except ValueError as e:
        return {"error": str(e)}
    out = []
    for c in range(a.channels):
        out.append({m: [None if not math.isfinite(x) else float(x) for x in a[m][c]] for m in _analysis.METRICS})
    return {"bands_hz": list(_analysis.BANDS_HZ), "channels": out}


# ---------------------------------------------------------------- shards

def _shard_range(spec, k):
    s = spec["shard_size"]
    return range(k * s, min((k + 1) * s, spec["count"]))


def _shard_count(spec):
    return (spec["count"] + spec["shard_size"] - 1) // spec["shard_size"]


def _shard_path(out_dir, spec, k):
    ext = ".h5" if spec["format"] == "hdf5" else ""
    return os.path.join(out_dir, "shards", f"shard-{k:05d}{ext}")


def _shard_complete(out_dir, spec, k):
    """A shard counts only under its final name, which it gets by rename
    once it is whole and flushed, and only while every IR its manifest lists
    is there in the manifest's shape: one lost or cut since (a disk error, a
    copy that stopped) makes the shard incomplete, so make makes it again.
    Reads the files' sizes and the HDF5 datasets' shapes, not their samples."""
    p = _shard_path(out_dir, spec, k)
    try:
        rows = _shard_manifest(p, spec)
        if [r["id"] for r in rows] != list(_shard_range(spec, k)):
            return False
        if spec["format"] == "hdf5":
            import h5py
            with h5py.File(p, "r") as f:
                for r in rows:
                    ds = f.get(f"ir/{r['id']:08d}")
                    if (not isinstance(ds, h5py.Dataset) or ds.dtype != np.float32
                            or ds.shape != (r["channels"], r["frames"])):
                        return False
        else:
            for r in rows:
                w = os.path.join(p, f"ir-{r['id']:08d}.wav")
                if os.path.getsize(w) != _WAV_HEADER_BYTES + 4 * r["channels"] * r["frames"]:
                    return False
    except Exception:
        return False
    return True


def _shard_manifest(path, spec):
    if spec["format"] == "hdf5":
        import h5py
        with h5py.File(path, "r") as f:
            if not bool(f.attrs.get("complete", False)):
                raise ValueError("incomplete")
            return json.loads(f["manifest"][()])
    with open(os.path.join(path, "manifest.jsonl"), "rb") as f:
        return [json.loads(line) for line in f if line.strip()]


def _fsync_dir(path):
    try:
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError:
        pass


def run_shard(spec, out_dir, k):
    """Makes shard k (on whichever worker runs it) and returns its manifest
    rows. Writes under a temporary name, renamed when complete."""
    if _shard_complete(out_dir, spec, k):
        return _shard_manifest(_shard_path(out_dir, spec, k), spec)
    rooms = _room_list(spec)
    results = []
    for i in _shard_range(spec, k):
        entry, rk = rooms[i % len(rooms)]
        desc = _room_description(spec, entry, rk)
        scene = _scene(desc, spec["allow_outside_paths"])
        src, lis = _place(spec, scene, i, desc["name"])
        t0 = time.perf_counter()
        r = scene.ir(src, lis, seed=spec["seed"] + i, threads=1, receiver=spec["receiver"],
                     quality=spec["quality"], sample_rate=float(spec["sample_rate"]), **spec["ir_options"])
        wall_ms = (time.perf_counter() - t0) * 1e3
        row = {"id": i, "shard": k, "room_index": i % len(rooms), "room": desc, **r.params,
               "time_ms": {**r.time_ms, "wall": wall_ms}, "frames": int(r.samples.shape[1]),
               "channels": int(r.samples.shape[0]), "sample_rate": r.sample_rate,
               "decay": r.stats["decay"], "warnings": r.warnings,
               "metrics": _metrics(r.samples, r.sample_rate)}
        results.append((i, r.samples, row))
    final = _shard_path(out_dir, spec, k)
    tmp = f"{final}.tmp-{os.getpid()}"
    rows = [row for _, _, row in results]
    if spec["format"] == "hdf5":
        import h5py
        with h5py.File(tmp, "w") as f:
            for i, samples, row in results:
                ds = f.create_dataset(f"ir/{i:08d}", data=samples)
                ds.attrs["params"] = json.dumps(row)
            f.create_dataset("manifest", data=json.dumps(rows))
            f.attrs["format_version"] = _FORMAT_VERSION
            f.attrs["complete"] = True
            f.flush()
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, final)
    else:
        os.makedirs(tmp, exist_ok=True)
        for i, samples, row in results:
            _write_wav_float(os.path.join(tmp, f"ir-{i:08d}.wav"), samples, row["sample_rate"])
        with open(os.path.join(tmp, "manifest.jsonl"), "w") as f:
            for row in rows:
                f.write(json.dumps(row) + "\n")
            f.flush()
            os.fsync(f.fileno())
        _fsync_dir(tmp)
        if _shard_complete(out_dir, spec, k):  # another worker finished it first: identical by construction
            _remove(tmp)
        else:
            if os.path.lexists(final):  # a damaged shard, made again: set aside, then removed
                old = f"{final}.tmp-{os.getpid()}-damaged"
                os.rename(final, old)
                _remove(old)
            os.rename(tmp, final)
    _fsync_dir(os.path.dirname(final))
    return rows


def _remove(path):
    """Removes a file or a folder (a shard's leftovers); what cannot be
    removed stays (a later make removes its .tmp- names)."""
    import shutil
    if os.path.isdir(path) and not os.path.islink(path):
        shutil.rmtree(path, ignore_errors=True)
    else:
        try:
            os.unlink(path)
        except OSError:
            pass


_WAV_HEADER_BYTES = 56  # RIFF, fmt (16), fact and data chunk headers, as _write_wav_float writes them


def _write_wav_float(path, samples, rate):
    """A 32-bit float WAV (WAVE_FORMAT_IEEE_FLOAT), channels interleaved."""
    c, n = samples.shape
    data = np.ascontiguousarray(samples.T, dtype="<f4").tobytes()
    fmt = struct.pack("<HHIIHH", 3, c, int(rate), int(rate) * 4 * c, 4 * c, 32)
    with open(path, "wb") as f:
        f.write(b"RIFF" + struct.pack("<I", 4 + 8 + len(fmt) + 8 + 4 + 8 + len(data)) + b"WAVE")
        f.write(b"fmt " + struct.pack("<I", len(fmt)) + fmt)
        f.write(b"fact" + struct.pack("<II", 4, n))
        f.write(b"data" + struct.pack("<I", len(data)) + data)


def read_wav_float(path):
    """(samples float32 (channels, frames), rate) of a 32-bit float WAV (as
    earshot writes them: format 3 or WAVE_FORMAT_EXTENSIBLE with float)."""
    with open(path, "rb") as f:
        b = f.read()
    if b[:4] != b"RIFF" or b[8:12] != b"WAVE":
        raise ValueError(f"{path}: not a WAV file")
    pos, fmt, data = 12, None, None
    while pos + 8 <= len(b):
        tag, size = b[pos:pos + 4], struct.unpack("<I", b[pos + 4:pos + 8])[0]
        body = b[pos + 8:pos + 8 + size]
        if tag == b"fmt ":
            fmt = struct.unpack("<HHIIHH", body[:16])
            if fmt[0] == 0xFFFE and len(body) >= 26:
                fmt = (struct.unpack("<H", body[24:26])[0],) + fmt[1:]
        elif tag == b"data":
            data = body
        pos += 8 + size + (size & 1)
    if fmt is None or data is None or fmt[0] != 3 or fmt[5] != 32:
        raise ValueError(f"{path}: not a 32-bit float WAV")
    c = fmt[1]
    x = np.frombuffer(data[:len(data) // (4 * c) * 4 * c], dtype="<f4").reshape(-1, c).T
    return np.ascontiguousarray(x, dtype=np.float32), float(fmt[2])


# ---------------------------------------------------------------- running

def _inputs(spec):
    out = []
    for r in spec["rooms"]:
        if "generator" not in r:  # a generated room's materials are names or numbers, not files
            out += [r[k] for k in ("geometry", "materials", "material_map") if r.get(k)]
    return out


def _folder_record(out_dir):
    """The folder's spec.json as make wrote it ({hash, format_version,
    earshot, spec}). One that is damaged, or not a dataset's, is a
    ValueError naming it (never its contents)."""
    path = os.path.join(out_dir, "spec.json")
    try:
        if os.path.getsize(path) > _MAX_SPEC_BYTES:
            raise _Damaged("over 16 MB")
        with open(path, "rb") as f:
            rec = json.loads(f.read())
        spec = rec["spec"]
        whole = (lambda v, hi: isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= hi)
        if not (isinstance(rec, dict) and isinstance(rec.get("hash"), str) and isinstance(spec, dict)
                and whole(spec.get("count"), _MAX_COUNT) and whole(spec.get("shard_size"), 100_000)
                and spec.get("format") in ("hdf5", "wav")):
            raise _Damaged("not as make writes it")
    except (ValueError, RecursionError, KeyError, TypeError) as e:
        raise ValueError(f"{path}: not a dataset's record ({_why(e)}); was the folder made by earshot.dataset, "
                         "and changed since?") from None
    return rec


def _prepare_dir(spec, out_dir, spec_path_in=None):
    # An output never replaces an input (the spec, a room's files).
    inputs = {os.path.realpath(p) for p in _inputs(spec) + ([spec_path_in] if spec_path_in else [])}
    for name in ("spec.json", "manifest.jsonl", "shards"):
        if os.path.realpath(os.path.join(out_dir, name)) in inputs:
            raise ValueError(f"{out_dir}: {name} would replace an input of the spec; choose another folder")
    if os.path.realpath(out_dir) in inputs:
        raise ValueError(f"{out_dir}: is an input of the spec")
    os.makedirs(os.path.join(out_dir, "shards"), exist_ok=True)
    spec_path = os.path.join(out_dir, "spec.json")
    h = _spec_hash(spec)
    if os.path.exists(spec_path):
        if _folder_record(out_dir)["hash"] != h:
            raise ValueError(f"{out_dir}: holds a dataset made from a different spec; use a new folder")
    else:
        tmp = spec_path + f".tmp-{os.getpid()}"
        with open(tmp, "w") as f:
            json.dump({"hash": h, "format_version": _FORMAT_VERSION, "earshot": earshot.__version__,
                       "spec": spec}, f, indent=1)
        os.replace(tmp, spec_path)
    # Temporary files of a killed run: never complete, removed.
    sd = os.path.join(out_dir, "shards")
    for n in os.listdir(sd):
        if ".tmp-" in n:
            _remove(os.path.join(sd, n))


def _write_manifest(out_dir, spec, n):
    """DIR/manifest.jsonl from the n shards' own manifests, one shard at a
    time; returns every IR's pipeline time (ms, an array of doubles)."""
    pipeline_ms = array("d")
    final = os.path.join(out_dir, "manifest.jsonl")
    tmp = final + f".tmp-{os.getpid()}"
    with open(tmp, "w") as f:
        for k in range(n):
            for r in _shard_manifest(_shard_path(out_dir, spec, k), spec):
                f.write(json.dumps(r) + "\n")
                pipeline_ms.append(r["time_ms"]["pipeline"])
    os.replace(tmp, final)
    return pipeline_ms


def make(spec, out_dir, *, workers=None, scheduler=None, in_process=False, progress=True,
         base_dir=None, allow_outside_paths=False):
    """Makes (or resumes) the dataset of `spec` (a path, or a dict whose
    paths are relative to base_dir) in out_dir. workers: a Dask LocalCluster
    of that many single-threaded worker processes (default: the cores);
    scheduler: the address of a running Dask scheduler instead; in_process:
    no Dask, shards made one after another here. Returns a summary dict
    (IRs, shards made and reused, seconds, seconds per IR)."""
    spec_path = None
    if isinstance(spec, (str, os.PathLike)):
        spec_path = os.fspath(spec)
        spec = read_spec(spec, allow_outside_paths=allow_outside_paths)
    elif isinstance(spec, dict) and "allow_outside_paths" not in spec:
        spec = resolve_spec(spec, base_dir or os.getcwd(), allow_outside_paths=allow_outside_paths)
    out_dir = os.path.abspath(os.fspath(out_dir))
    _prepare_dir(spec, out_dir, spec_path)
    n = _shard_count(spec)
    todo = [k for k in range(n) if not _shard_complete(out_dir, spec, k)]
    t0 = time.perf_counter()
    log = (lambda m: print(f"earshot dataset: {m}", file=sys.stderr, flush=True)) if progress else (lambda m: None)
    log(f"{spec['count']} IRs in {n} shards; {n - len(todo)} already made, {len(todo)} to make")
    # What make holds stays bounded whatever the count: a shard's rows are
    # dropped once it is written (the manifest is read back from the shards
    # at the end), and on Dask only a window of shards is in flight (each
    # future released once done), so neither this process nor the cluster
    # holds every row (~12 KiB each in memory: 11 GiB for a million IRs).
    if todo and (in_process or (workers == 0)):
        for j, k in enumerate(todo):
            run_shard(spec, out_dir, k)
            log(f"shard {k} done ({j + 1}/{len(todo)})")
    elif todo:
        from dask.distributed import Client, LocalCluster, as_completed
        cluster = None
        if scheduler:
            client = Client(scheduler)
        else:
            nw = workers or os.cpu_count() or 1
            cluster = LocalCluster(n_workers=nw, threads_per_worker=1, processes=True, dashboard_address=":0",
                                   silence_logs=40)
            client = Client(cluster)
        try:
            try:  # the dashboard needs bokeh, which Debian 12 does not package
                import bokeh  # noqa: F401
                log(f"Dask dashboard: {client.dashboard_link}")
            except ImportError:
                log("Dask dashboard: not available (it needs bokeh: Debian 12 has no python3-bokeh); "
                    "progress below")
            tag = _spec_hash(spec)[:8]
            pending = iter(todo)
            running = as_completed()

            def submit_next():
                k = next(pending, None)
                if k is not None:
                    running.add(client.submit(run_shard, spec, out_dir, k, key=f"earshot-shard-{k}-{tag}",
                                              pure=False))
            # Four shards a worker thread in flight (at least 16): enough to
            # keep a cluster busy, and workers that join later get work.
            for _ in range(max(16, 4 * sum(client.nthreads().values()))):
                submit_next()
            done = 0
            for fut in running:
                fut.result()  # raises a shard's error here
                fut.release()
                done += 1
                submit_next()
                if progress:
                    w = 30
                    f = done / len(todo)
                    el = time.perf_counter() - t0
                    print(f"\r[{'#' * int(f * w + .5)}{'.' * (w - int(f * w + .5))}] {done}/{len(todo)} shards, "
                          f"{el:.0f} s, {el / f * (1 - f):.0f} s left ", end="", file=sys.stderr, flush=True)
            if progress:
                print(file=sys.stderr)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    made_seconds = time.perf_counter() - t0
    pipeline_ms = _write_manifest(out_dir, spec, n)
    made = sum(len(_shard_range(spec, k)) for k in todo)
    summary = {"irs": spec["count"], "shards": n, "shards_made": len(todo), "shards_reused": n - len(todo),
               "irs_made": made, "seconds": made_seconds,
               "seconds_per_ir": made_seconds / made if made else None,
               "median_pipeline_ms": float(np.median(pipeline_ms))}
    log(f"made {made} IRs in {made_seconds:.1f} s ({summary['seconds_per_ir'] or 0:.3f} s per IR, median "
        f"pipeline {summary['median_pipeline_ms']:.1f} ms) in {out_dir}")
    return summary


def load(out_dir, *, partial=False):
    """Iterates (id, samples float32 (channels, frames), params) over a
    dataset in id order. An incomplete dataset raises ValueError unless
    partial=True (then only its complete shards)."""
    out_dir = os.fspath(out_dir)
    spec = _folder_record(out_dir)["spec"]
    damaged = (ValueError, KeyError, TypeError, OSError, struct.error, RecursionError)

    def failure(p, i, e):
        return ValueError(f"{p}: IR {i} is damaged ({_why(e)}); delete the shard and run make again to make it anew")
    for k in range(_shard_count(spec)):
        p = _shard_path(out_dir, spec, k)
        if not _shard_complete(out_dir, spec, k):
            if partial:
                continue
            raise ValueError(f"{out_dir}: shard {k} is missing, incomplete or damaged (run make again to "
                             "make it)")
        ids = _shard_range(spec, k)
        if spec["format"] == "hdf5":
            import h5py
            try:
                f = h5py.File(p, "r")
            except damaged as e:
                raise failure(p, ids[0], e) from None
            with f:
                for i in ids:
                    try:
                        x, params = _read_hdf5_ir(f, i)
                    except damaged as e:
                        raise failure(p, i, e) from None
                    yield i, x, params
        else:
            try:
                rows = {r["id"]: r for r in _shard_manifest(p, spec)}
            except damaged as e:
                raise failure(p, ids[0], e) from None
            for i in ids:
                try:
                    w = os.path.join(p, f"ir-{i:08d}.wav")
                    _check_size(os.path.getsize(w), f"{os.path.getsize(w)} bytes")
                    x, params = read_wav_float(w)[0], rows[i]
                except damaged as e:
                    raise failure(p, i, e) from None
                yield i, x, params


def _read_hdf5_ir(f, i):
    """IR i of an open HDF5 shard and its parameters. Its size is checked
    against the memory limit before it is read: a damaged file may claim
    any shape."""
    ds = f[f"ir/{i:08d}"]
    if len(ds.shape) != 2 or ds.dtype != np.float32 or not 1 <= ds.shape[0] <= 16:
        raise _Damaged("not an IR")
    _check_size(ds.shape[0] * ds.shape[1] * 4, f"{ds.shape[0]} x {ds.shape[1]} samples")
    return ds[()], json.loads(ds.attrs["params"])


def main(argv=None):
    import argparse
    ap = argparse.ArgumentParser(prog="python3 -m earshot dataset",
                                 description="Make (or resume) a dataset of IRs from a spec file (see "
                                             "earshot.dataset's documentation for the spec).")
    ap.add_argument("spec", help="spec file (JSON)")
    ap.add_argument("-o", "--output", required=True, help="dataset folder (created; resumed if it exists)")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--workers", type=int, default=None,
                   help="Dask LocalCluster of N single-threaded worker processes (default: the cores)")
    g.add_argument("--scheduler", default=None, help="address of a running Dask scheduler (tcp://host:8786)")
    g.add_argument("--in-process", action="store_true", help="no Dask: make the shards one by one here")
    ap.add_argument("--allow-outside-paths", action="store_true",
                    help="let the spec name files outside its folder")
    ap.add_argument("--quiet", action="store_true", help="no progress")
    a = ap.parse_args(argv)
    if a.workers is not None and not 1 <= a.workers <= 1024:
        ap.error("--workers: expected 1 .. 1024")
    try:
        s = make(a.spec, a.output, workers=a.workers, scheduler=a.scheduler, in_process=a.in_process,
                 progress=not a.quiet, allow_outside_paths=a.allow_outside_paths)
    except (ValueError, OSError, TypeError) as e:
        print(f"earshot dataset: error: {e}", file=sys.stderr)
        return 2
    print(json.dumps(s))
    return 0
