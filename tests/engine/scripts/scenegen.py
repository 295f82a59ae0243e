"""Small glTF scenes and .shprobe files for the engine tests, written with numpy only.

The .shprobe writer here is an independent implementation of DESIGN.md §4 (version 1), so the
engine's reader (the bake core's pb_shprobe_read) is checked against the documented layout, not
against itself. glTF files embed their buffer as a data: URI unless told otherwise.
"""
import base64
import json
import struct
from pathlib import Path

import numpy as np

SHPROBE_MAGIC = 0x52485053


def write_shprobe_v1(path, coeffs, grid, origin, spacing, scale=None, ambient=None,
                     default_scale=1.0, default_ambient=0.1):
    """Writes a version-1 .shprobe. coeffs: (count, 9, 3) radiance SH; grid: int array (Z, Y, X)
    holding probe indices or -1 (flattened as x + y*X + z*X*Y)."""
    coeffs = np.asarray(coeffs, dtype=np.float32).reshape(-1, 9, 3)
    count = coeffs.shape[0]
    grid = np.asarray(grid, dtype=np.int32)
    Z, Y, X = grid.shape
    scale = np.ones(count, np.float32) if scale is None else np.asarray(scale, np.float32)
    ambient = np.full(count, default_ambient, np.float32) if ambient is None else np.asarray(ambient, np.float32)
    out = bytearray()
    out += struct.pack("<III", SHPROBE_MAGIC, 1, count)
    out += struct.pack("<III", X, Y, Z)
    out += struct.pack("<3f", *origin)
    out += struct.pack("<fff", spacing, default_scale, default_ambient)
    for p in range(count):
        c4 = np.zeros((9, 4), np.float32)
        c4[:, :3] = coeffs[p]
        out += c4.tobytes()
        out += struct.pack("<ff", scale[p], ambient[p]) + b"\0" * 8
    out += grid.astype("<i4").tobytes()  # (Z, Y, X) C order == x + y*X + z*X*Y
    Path(path).write_bytes(bytes(out))
    return bytes(out)


def uv_sphere(radius=1.0, segments=128, rings=64):
    """Positions, analytic unit normals, uvs and CCW triangle indices of a UV sphere."""
    th = np.linspace(0.0, np.pi, rings + 1)
    ph = np.linspace(0.0, 2.0 * np.pi, segments + 1)
    T, P = np.meshgrid(th, ph, indexing="ij")
    n = np.stack([np.sin(T) * np.cos(P), np.cos(T), -np.sin(T) * np.sin(P)], axis=-1).reshape(-1, 3)
    uv = np.stack([P / (2 * np.pi), T / np.pi], axis=-1).reshape(-1, 2)
    idx = []
    for r in range(rings):
        for s in range(segments):
            a = r * (segments + 1) + s
            b = a + segments + 1
            idx += [a, b, a + 1, a + 1, b, b + 1]
    return (n * radius).astype(np.float32), n.astype(np.float32), uv.astype(np.float32), np.array(idx, np.uint32)


def cube(half=0.5):
    """24-vertex cube with face normals, CCW outward."""
    pos, nrm, idx = [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u = np.zeros(3)
            u[(axis + 1) % 3] = 1.0
            v = np.cross(n, u)
            base = len(pos)
            for du, dv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                pos.append((n + du * u + dv * v) * half)
                nrm.append(n)
            idx += [base, base + 1, base + 2, base, base + 2, base + 3]
    return (np.array(pos, np.float32), np.array(nrm, np.float32),
            np.zeros((len(pos), 2), np.float32), np.array(idx, np.uint32))


def quad(size_u, size_v, normal_axis=1, sign=1.0):
    """A two-triangle rectangle centred on the origin, normal along +/- axis `normal_axis`,
    extents size_u, size_v along the next two axes (cyclic), CCW seen from the normal side."""
    n = np.zeros(3)
    n[normal_axis] = sign
    u = np.zeros(3)
    u[(normal_axis + 1) % 3] = 0.5 * size_u
    v = np.zeros(3)
    v[(normal_axis + 2) % 3] = 0.5 * size_v
    pos = np.array([-u - v, u - v, u + v, -u + v])
    idx = [0, 1, 2, 0, 2, 3] if np.dot(np.cross(u, v), n) > 0 else [0, 2, 1, 0, 3, 2]
    return (pos.astype(np.float32), np.tile(n, (4, 1)).astype(np.float32),
            np.zeros((4, 2), np.float32), np.array(idx, np.uint32))


ROT_LOOK_DOWN = (-0.7071067811865476, 0.0, 0.0, 0.7071067811865476)  # camera -Z -> world -Y, up -> -Z
ROT_LOOK_POS_X = (0.0, -0.7071067811865476, 0.0, 0.7071067811865476)  # camera -Z -> world +X, up +Y


class GltfBuilder:
    """Accumulates meshes, nodes, materials into one glTF 2.0 document with one buffer."""

    def __init__(self):
        self.bin = bytearray()
        self.doc = {"asset": {"version": "2.0", "generator": "schnee tests/engine scenegen"},
                    "scene": 0, "scenes": [{"nodes": []}], "nodes": [], "meshes": [],
                    "materials": [], "accessors": [], "bufferViews": [], "buffers": []}

    def _view(self, data, target):
        while len(self.bin) % 4:
            self.bin.append(0)
        off = len(self.bin)
        self.bin += data
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": off, "byteLength": len(data), "target": target})
        return len(self.doc["bufferViews"]) - 1

    def _accessor(self, arr, kind):
        arr = np.ascontiguousarray(arr)
        if kind == "SCALAR":
            view = self._view(arr.astype("<u4").tobytes(), 34963)
            acc = {"bufferView": view, "componentType": 5125, "count": int(arr.size), "type": "SCALAR"}
        else:
            view = self._view(arr.astype("<f4").tobytes(), 34962)
            acc = {"bufferView": view, "componentType": 5126, "count": int(arr.shape[0]), "type": kind}
            if kind == "VEC3":
                acc["min"] = [float(x) for x in arr.min(axis=0)]
                acc["max"] = [float(x) for x in arr.max(axis=0)]
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def material(self, name, base_color=(1, 1, 1, 1), sh_scale=None, ambient_term=None, emissive=(0, 0, 0),
                 metallic=0.0, roughness=1.0, probe_mode=None):
        m = {"name": name, "pbrMetallicRoughness": {"baseColorFactor": list(base_color),
                                                     "metallicFactor": metallic, "roughnessFactor": roughness},
             "emissiveFactor": list(emissive)}
        if sh_scale is not None or ambient_term is not None or probe_mode is not None:
            ext = {}
            if sh_scale is not None:
                ext["shScale"] = sh_scale
            if ambient_term is not None:
                ext["ambientTerm"] = ambient_term
            if probe_mode is not None:
                ext["probeMode"] = probe_mode
            m["extensions"] = {"VULKAN_SCHNEE_materials": ext}
            self._use("VULKAN_SCHNEE_materials")
        self.doc["materials"].append(m)
        return len(self.doc["materials"]) - 1

    def mesh(self, name, geometry, material=None):
        pos, nrm, uv, idx = geometry
        prim = {"attributes": {"POSITION": self._accessor(pos, "VEC3"), "NORMAL": self._accessor(nrm, "VEC3"),
                               "TEXCOORD_0": self._accessor(uv, "VEC2")},
                "indices": self._accessor(idx, "SCALAR")}
        if material is not None:
            prim["material"] = material
        self.doc["meshes"].append({"name": name, "primitives": [prim]})
        return len(self.doc["meshes"]) - 1

    def node(self, name, mesh=None, translation=None, parent=None, camera=None, rotation=None, **extra):
        n = {"name": name}
        if mesh is not None:
            n["mesh"] = mesh
        if camera is not None:
            n["camera"] = camera
        if translation is not None:
            n["translation"] = [float(x) for x in translation]
        if rotation is not None:
            n["rotation"] = [float(x) for x in rotation]
        n.update(extra)
        self.doc["nodes"].append(n)
        i = len(self.doc["nodes"]) - 1
        if parent is None:
            self.doc["scenes"][0]["nodes"].append(i)
        else:
            self.doc["nodes"][parent].setdefault("children", []).append(i)
        return i

    def camera(self, name, yfov, znear=0.05, zfar=100.0):
        self.doc.setdefault("cameras", []).append(
            {"name": name, "type": "perspective", "perspective": {"yfov": yfov, "znear": znear, "zfar": zfar}})
        return len(self.doc["cameras"]) - 1

    def ortho_camera(self, name, ymag, xmag=None, znear=0.01, zfar=100.0):
        self.doc.setdefault("cameras", []).append(
            {"name": name, "type": "orthographic",
             "orthographic": {"xmag": xmag or ymag, "ymag": ymag, "znear": znear, "zfar": zfar}})
        return len(self.doc["cameras"]) - 1

    def probe_grids(self, entries, sky=None):
        props = {"shProbeGrids": entries}
        if sky is not None:
            props["sky"] = sky
        self.doc["scenes"][0].setdefault("extensions", {})["VULKAN_SCHNEE_engine_properties"] = props
        self._use("VULKAN_SCHNEE_engine_properties")

    def light(self, name, type_, color=(1, 1, 1), intensity=1.0, schnee_mode=None, range_=None,
              intensity_scale=None, cone=None):
        """A KHR_lights_punctual light; schnee_mode ("baked", "mixed", "realtime" or any value) adds
        extensions.VULKAN_SCHNEE_light = {"mode": schnee_mode}, with "intensityScale" when
        intensity_scale is given (docs/export.md). cone = (inner, outer) radians: a spot's angles."""
        ext = self.doc.setdefault("extensions", {}).setdefault("KHR_lights_punctual", {"lights": []})
        light = {"name": name, "type": type_, "color": list(color), "intensity": intensity}
        if range_ is not None:
            light["range"] = float(range_)
        if cone is not None:
            light["spot"] = {"innerConeAngle": float(cone[0]), "outerConeAngle": float(cone[1])}
        if schnee_mode is not None:
            light["extensions"] = {"VULKAN_SCHNEE_light": {"mode": schnee_mode}}
            if intensity_scale is not None:
                light["extensions"]["VULKAN_SCHNEE_light"]["intensityScale"] = intensity_scale
            self._use("VULKAN_SCHNEE_light")
        ext["lights"].append(light)
        self._use("KHR_lights_punctual")
        return len(ext["lights"]) - 1

    def light_node(self, name, light, translation=None, rotation=None):
        """A node carrying light index `light` (KHR_lights_punctual)."""
        return self.node(name, translation=translation, rotation=rotation,
                         extensions={"KHR_lights_punctual": {"light": light}})

    def _use(self, ext):
        used = self.doc.setdefault("extensionsUsed", [])
        if ext not in used:
            used.append(ext)

    def write(self, path):
        self.doc["buffers"] = [{"byteLength": len(self.bin),
                                "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(self.bin)).decode()}]
        Path(path).write_text(json.dumps(self.doc, indent=1))
        return Path(path)


def grid_entry(name, uri, count, origin, dims, spacing, max_band=2):
    return {"name": name, "uri": uri, "probeCount": count, "maxBand": max_band,
            "gridOrigin": list(map(float, origin)), "gridDims": list(map(int, dims)), "gridSpacing": float(spacing),
            "gridAxes": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}


def write_exr(path, img):
    """Writes an (H, W, 3) float image as a 32-bit float EXR: numpy -> PFM -> oiiotool."""
    import subprocess
    img = np.asarray(img, np.float32)
    h, w = img.shape[:2]
    pfm = Path(str(path) + ".pfm")
    # PFM: rows bottom to top, little-endian (negative scale).
    pfm.write_bytes(b"PF\n%d %d\n-1.0\n" % (w, h) + np.ascontiguousarray(img[::-1]).astype("<f4").tobytes())
    subprocess.run(["oiiotool", str(pfm), "-d", "float", "-o", str(path)], check=True, capture_output=True)
    pfm.unlink()
    return Path(path)


def sky_entry(uri, sh):
    """The VULKAN_SCHNEE_engine_properties.sky member (docs/export.md)."""
    sh = np.asarray(sh, float).reshape(-1, 3)
    band = int(round(np.sqrt(len(sh)))) - 1
    return {"uri": uri, "maxBand": band, "sh": [[float(v) for v in row] for row in sh]}
