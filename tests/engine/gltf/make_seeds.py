#!/usr/bin/env python3
"""Writes a small seed corpus of valid glTF inputs (JSON with data: URIs, and GLB) for the glTF
fuzz target, plus a libFuzzer dictionary of glTF keywords.

Usage: make_seeds.py OUT_DIR DICT_FILE   (standard library only; every input is self-contained,
since the fuzz target loads from memory without a base directory)."""
import base64
import json
import os
import struct
import sys


def data_uri(b):
    return "data:application/octet-stream;base64," + base64.b64encode(b).decode()


def glb(doc, bin_bytes):
    j = json.dumps(doc, separators=(",", ":")).encode()
    j += b" " * (-len(j) % 4)
    b = bin_bytes + b"\0" * (-len(bin_bytes) % 4)
    total = 12 + 8 + len(j) + (8 + len(b) if bin_bytes else 0)
    out = struct.pack("<III", 0x46546C67, 2, total) + struct.pack("<II", len(j), 0x4E4F534A) + j
    if bin_bytes:
        out += struct.pack("<II", len(b), 0x004E4942) + b
    return out


def cube():
    """Unit cube: 24 vertices (pos, normal, uv), ushort indices; returns (bytes, views, accessors)."""
    pos, nrm, uv = [], [], []
    faces = [((1, 0, 0), (0, 1, 0)), ((-1, 0, 0), (0, 1, 0)), ((0, 1, 0), (0, 0, 1)),
             ((0, -1, 0), (0, 0, 1)), ((0, 0, 1), (1, 0, 0)), ((0, 0, -1), (1, 0, 0))]
    for n, u in faces:
        v = (n[1] * u[2] - n[2] * u[1], n[2] * u[0] - n[0] * u[2], n[0] * u[1] - n[1] * u[0])
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            pos.append(tuple(n[k] + su * u[k] + sv * v[k] for k in range(3)))
            nrm.append(n)
            uv.append(((su + 1) / 2, (sv + 1) / 2))
    idx = []
    for f in range(6):
        idx += [4 * f, 4 * f + 1, 4 * f + 2, 4 * f, 4 * f + 2, 4 * f + 3]
    b = b"".join(struct.pack("<3f", *p) for p in pos)
    b += b"".join(struct.pack("<3f", *p) for p in nrm)
    b += b"".join(struct.pack("<2H", int(x * 65535), int(y * 65535)) for x, y in uv)
    b += b"".join(struct.pack("<H", i) for i in idx)
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": 288},
             {"buffer": 0, "byteOffset": 288, "byteLength": 288},
             {"buffer": 0, "byteOffset": 576, "byteLength": 96},
             {"buffer": 0, "byteOffset": 672, "byteLength": 72}]
    accs = [{"bufferView": 0, "componentType": 5126, "count": 24, "type": "VEC3",
             "min": [-1, -1, -1], "max": [1, 1, 1]},
            {"bufferView": 1, "componentType": 5126, "count": 24, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5123, "normalized": True, "count": 24, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 36, "type": "SCALAR"}]
    return b, views, accs


def full_doc(buffer):
    b, views, accs = cube()
    doc = {
        "asset": {"version": "2.0", "generator": "make_seeds.py"},
        "extensionsUsed": ["KHR_lights_punctual", "VULKAN_SCHNEE_engine_properties", "VULKAN_SCHNEE_materials"],
        "scene": 0,
        "scenes": [{"name": "Scene", "nodes": [0, 3, 4], "extensions": {"VULKAN_SCHNEE_engine_properties": {
            "shProbeGrids": [{"name": "probes", "uri": "sh_coeffs/probes.shprobe", "probeCount": 8,
                              "maxBand": 2, "gridOrigin": [-1, 0, -1], "gridDims": [2, 2, 2],
                              "gridSpacing": 1.0, "gridAxes": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}]}}}],
        "nodes": [{"name": "Root", "translation": [0, 1, 0], "rotation": [0, 0.3826834, 0, 0.9238795],
                   "scale": [1, 2, 1], "children": [1, 2]},
                  {"name": "Cube", "mesh": 0},
                  {"name": "Child", "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 3, 0, 0, 1], "mesh": 0},
                  {"name": "Camera", "camera": 0, "translation": [0, 2, 8]},
                  {"name": "Light", "rotation": [-0.7071068, 0, 0, 0.7071068],
                   "extensions": {"KHR_lights_punctual": {"light": 0}}}],
        "meshes": [{"name": "Cube", "primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
                                                    "indices": 3, "material": 0, "mode": 4}]}],
        "materials": [{"name": "Movable", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.1, 0.1, 1],
                                                                   "metallicFactor": 0, "baseColorTexture": {"index": 0}},
                       "extensions": {"VULKAN_SCHNEE_materials": {"shScale": 1.0, "ambientTerm": 0.1}},
                       "doubleSided": True, "alphaMode": "MASK", "alphaCutoff": 0.4}],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 33071}],
        "images": [{"bufferView": 2, "mimeType": "image/png"}],
        "cameras": [{"name": "Camera", "type": "perspective",
                     "perspective": {"yfov": 0.7, "znear": 0.1, "zfar": 100, "aspectRatio": 1.78}}],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"name": "Sun", "type": "directional", "color": [1, 1, 1], "intensity": 3},
            {"type": "spot", "spot": {"innerConeAngle": 0.1, "outerConeAngle": 0.6}, "range": 5}]}},
        "bufferViews": views,
        "accessors": accs,
        "buffers": [buffer(b)],
    }
    return doc, b


def main():
    out, dict_path = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    seeds = {}
    doc, b = full_doc(lambda b: {"byteLength": len(b), "uri": data_uri(b)})
    seeds["full.gltf"] = json.dumps(doc).encode()
    doc_glb, b = full_doc(lambda b: {"byteLength": len(b)})
    seeds["full.glb"] = glb(doc_glb, b)

    # Interleaved (stride 20) + sparse + strips/fans.
    inter = b"".join(struct.pack("<3f2HBBBB", i, 2 * i, 3 * i, i * 20000, 65535 - i * 20000, 255, i, 0, 255)
                     for i in range(4))
    sparse = struct.pack("<2H", 1, 3) + struct.pack("<6f", 0, 5, 0, 0, 0, 5)
    buf = inter + sparse
    seeds["interleaved_sparse.gltf"] = json.dumps({
        "asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "COLOR_0": 2}, "mode": 5},
            {"attributes": {"POSITION": 3}, "mode": 6},
            {"attributes": {"POSITION": 0}, "mode": 0}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 0, "byteOffset": 12, "componentType": 5123, "normalized": True, "count": 4, "type": "VEC2"},
            {"bufferView": 0, "byteOffset": 16, "componentType": 5121, "normalized": True, "count": 4, "type": "VEC4"},
            {"componentType": 5126, "count": 4, "type": "VEC3", "sparse": {
                "count": 2, "indices": {"bufferView": 1, "componentType": 5123}, "values": {"bufferView": 2}}}],
        "bufferViews": [{"buffer": 0, "byteLength": 80, "byteStride": 20},
                        {"buffer": 0, "byteOffset": 80, "byteLength": 4},
                        {"buffer": 0, "byteOffset": 84, "byteLength": 24}],
        "buffers": [{"byteLength": len(buf), "uri": data_uri(buf)}]}).encode()
    seeds["minimal.gltf"] = b'{"asset":{"version":"2.0"}}'
    seeds["ortho_nodes.gltf"] = json.dumps({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"children": [1, 2]}, {"camera": 0}, {"children": [3]}, {"scale": [2, 2, 2]}],
        "cameras": [{"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0, "zfar": 10}}]}).encode()
    for name, data in seeds.items():
        with open(os.path.join(out, name), "wb") as f:
            f.write(data)

    words = ["asset", "version", "2.0", "scene", "scenes", "nodes", "children", "mesh", "meshes", "camera",
             "cameras", "primitives", "attributes", "POSITION", "NORMAL", "TANGENT", "TEXCOORD_0",
             "TEXCOORD_1", "COLOR_0", "indices", "material", "materials", "mode", "accessors", "bufferView",
             "bufferViews", "byteOffset", "byteLength", "byteStride", "componentType", "normalized", "count",
             "type", "SCALAR", "VEC2", "VEC3", "VEC4", "MAT4", "sparse", "values", "buffers", "buffer", "uri",
             "data:application/octet-stream;base64,", "matrix", "translation", "rotation", "scale",
             "extensions", "extensionsRequired", "KHR_lights_punctual", "lights", "light", "spot",
             "innerConeAngle", "outerConeAngle", "directional", "point", "perspective", "orthographic",
             "yfov", "znear", "zfar", "xmag", "ymag", "pbrMetallicRoughness", "baseColorFactor",
             "baseColorTexture", "index", "texCoord", "textures", "images", "samplers", "source", "sampler",
             "mimeType", "VULKAN_SCHNEE_materials", "shScale", "ambientTerm",
             "VULKAN_SCHNEE_engine_properties", "shProbeGrids", "gridDims", "gridOrigin", "gridSpacing",
             "gridAxes", "probeCount", "maxBand", "5126", "5123", "5121", "5125", "5120", "5122"]
    with open(dict_path, "w") as f:
        for w in words:
            f.write('"%s"\n' % w.replace("\\", "\\\\").replace('"', '\\"'))
        f.write('"glTF"\n"JSON"\n"BIN\\x00"\n')


if __name__ == "__main__":
    main()
