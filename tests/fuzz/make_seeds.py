#!/usr/bin/env python3
"""Writes the hand-made seed inputs of the fuzz targets into corpus/<target>/.

Wire messages are encoded by protoc (--encode, from their text format), so the seeds follow
the proto as it is. Run from anywhere: python3 tests/fuzz/make_seeds.py. Inputs that the
fuzzers found (crashes turned into regression inputs) sit beside these, named crash-*.
"""
import base64
import json
import pathlib
import struct
import subprocess

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
PROTO = "skinserve/v1/skinning.proto"


def encode(message_type, text):
    return subprocess.run(
        ["protoc", f"--proto_path={ROOT / 'proto'}", f"--encode=skinserve.v1.{message_type}", PROTO],
        input=text.encode(), capture_output=True, check=True).stdout


def varint(n):
    out = bytearray()
    while True:
        byte = n & 0x7F
        n >>= 7
        out.append(byte | (0x80 if n else 0))
        if not n:
            return bytes(out)


def delimited(messages):
    return b"".join(varint(len(m)) + m for m in messages)


def octal(data):
    return "".join(f"\\{b:03o}" for b in data)


def floats(values):
    return struct.pack(f"<{len(values)}f", *values)


def write(target, name, data):
    folder = HERE / "corpus" / target
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_bytes(data)


def upload_seeds():
    # A 4-vertex quad, 2 influences, 2 joints, with normals; arrays in two chunks each.
    v = 4
    positions = floats([0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0])
    normals = floats([0, 0, 1] * v)
    joints = struct.pack("<8H", 0, 1, 0, 1, 1, 0, 1, 0)
    weights = floats([0.75, 0.25, 0.5, 0.5, 1.0, 0.0, 0.6, 0.4])

    def header(policy="WEIGHT_POLICY_REJECT", normals_flag="true"):
        return encode("UploadMeshRequest", f"header {{ vertex_count: {v} influences: 2 joint_count: 2 "
                      f"has_normals: {normals_flag} weight_policy: {policy} }}")

    def chunk(array, offset, data):
        return encode("UploadMeshRequest",
                      f'chunk {{ array: {array} offset: {offset} data: "{octal(data)}" }}')

    def halves(array, data, size):
        half = len(data) // size // 2
        return [chunk(array, 0, data[:half * size]), chunk(array, half, data[half * size:])]

    body = (halves("MESH_ARRAY_POSITIONS", positions, 4) + halves("MESH_ARRAY_NORMALS", normals, 4) +
            halves("MESH_ARRAY_JOINTS", joints, 2) + halves("MESH_ARRAY_WEIGHTS", weights, 4))
    write("mesh_upload_fuzzer", "quad_normals", delimited([header()] + body))
    no_normals = body[:2] + body[4:]
    write("mesh_upload_fuzzer", "quad_no_normals", delimited([header(normals_flag="false")] + no_normals))
    unnormalized = floats([3, 1, 1, 1, 2, 0, 6, 4])
    write("mesh_upload_fuzzer", "quad_normalize",
          delimited([header("WEIGHT_POLICY_NORMALIZE")] + body[:6] +
                    [chunk("MESH_ARRAY_WEIGHTS", 0, unnormalized)]))
    write("mesh_upload_fuzzer", "truncated", delimited([header()] + body[:3]))
    write("mesh_upload_fuzzer", "chunk_first", delimited(body[:1] + [header()]))


def request_seeds():
    joints = 8
    identity = floats([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0] * joints)
    shifted = floats([1, 0, 0, 0.5, 0, 1, 0, -1, 0, 0, 1, 2] * joints)
    write("skin_request_fuzzer", "identity_normals",
          encode("SkinRequest", f'mesh_id: "m" frame: 7 palette: "{octal(identity)}" want_normals: true'))
    write("skin_request_fuzzer", "translate",
          encode("SkinRequest", f'mesh_id: "m" backend: "serial" frame: 1 palette: "{octal(shifted)}"'))
    write("skin_request_fuzzer", "short_palette",
          encode("SkinRequest", f'mesh_id: "m" palette: "{octal(identity[:-5])}"'))
    nan = floats([float("nan")] * 12 * joints)
    write("skin_request_fuzzer", "nan_palette",
          encode("SkinRequest", f'mesh_id: "m" palette: "{octal(nan)}"'))
    write("skin_request_fuzzer", "unknown_mesh",
          encode("SkinRequest", f'mesh_id: "nope" palette: "{octal(identity)}"'))
    write("skin_request_fuzzer", "unknown_backend",
          encode("SkinRequest", f'mesh_id: "m" backend: "gpu9" palette: "{octal(identity)}"'))


def gltf_seed():
    # A skinned triangle: two joints (root and child), 4 influences, a LINEAR rotation clip
    # and a STEP translation clip, every buffer in one data: URI.
    positions = floats([0, 0, 0, 1, 0, 0, 0, 1, 0])
    normals = floats([0, 0, 1] * 3)
    joints = bytes([0, 1, 0, 0] * 3)
    weights = floats([0.5, 0.5, 0, 0] * 3)
    inverse_bind = floats([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1] * 2)
    times = floats([0, 1])
    rotations = floats([0, 0, 0, 1, 0, 0, 0.7071068, 0.7071068])
    translations = floats([0, 0, 0, 0, 1, 0])
    indices = struct.pack("<3H", 0, 1, 2) + b"\0\0"
    parts = [positions, normals, joints, weights, inverse_bind, times, rotations, translations,
             indices]
    views, offset = [], 0
    for p in parts:
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(p)})
        offset += len(p)
    blob = b"".join(parts)
    acc = [
        {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
         "min": [0, 0, 0], "max": [1, 1, 0]},
        {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"},
        {"bufferView": 2, "componentType": 5121, "count": 3, "type": "VEC4"},
        {"bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC4"},
        {"bufferView": 4, "componentType": 5126, "count": 2, "type": "MAT4"},
        {"bufferView": 5, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0], "max": [1]},
        {"bufferView": 6, "componentType": 5126, "count": 2, "type": "VEC4"},
        {"bufferView": 7, "componentType": 5126, "count": 2, "type": "VEC3"},
        {"bufferView": 8, "componentType": 5123, "count": 3, "type": "SCALAR"},
    ]
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 2]}],
        "nodes": [{"name": "root", "children": [1]},
                  {"name": "child", "translation": [0, 1, 0]},
                  {"name": "mesh", "mesh": 0, "skin": 0}],
        "meshes": [{"name": "tri", "primitives": [{"attributes": {
            "POSITION": 0, "NORMAL": 1, "JOINTS_0": 2, "WEIGHTS_0": 3}, "indices": 8}]}],
        "skins": [{"joints": [0, 1], "inverseBindMatrices": 4, "skeleton": 0}],
        "animations": [{"name": "bend", "samplers": [
            {"input": 5, "output": 6, "interpolation": "LINEAR"},
            {"input": 5, "output": 7, "interpolation": "STEP"}],
            "channels": [{"sampler": 0, "target": {"node": 1, "path": "rotation"}},
                         {"sampler": 1, "target": {"node": 0, "path": "translation"}}]}],
        "accessors": acc,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
    }
    write("gltf_fuzzer", "skinned_triangle.gltf", json.dumps(doc).encode())


def gltf_rigid_quantized_seed():
    # A rigid part (a mesh node without a skin) under an animated node, stored as
    # KHR_mesh_quantization writes it: int16 positions dequantized by the node's scale, one
    # vertex substituted through a sparse accessor (uint8 index), int8 normalized normals.
    positions = struct.pack("<12h", 0, 0, 0, 0, 7, 7, 7, 0, 0, 100, 0, 0)  # 3 x (xyz + pad)
    normals = struct.pack("<12b", 0, 0, 127, 0, 0, 0, 127, 0, 0, 0, 127, 0)
    sparse_index = bytes([1, 0, 0, 0])
    sparse_value = struct.pack("<3h", 100, 0, 0) + b"\0\0"
    times = floats([0, 1])
    rotations = struct.pack("<8h", 0, 0, 0, 32767, 0, 0, 23170, 23170)  # normalized short
    indices = struct.pack("<3H", 0, 1, 2) + b"\0\0"
    parts = [positions, normals, sparse_index, sparse_value, times, rotations, indices]
    views, offset = [], 0
    for p in parts:
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(p)})
        offset += len(p)
    views[0]["byteStride"] = 8
    views[1]["byteStride"] = 4
    blob = b"".join(parts)
    acc = [
        {"bufferView": 0, "componentType": 5122, "count": 3, "type": "VEC3",
         "min": [0, 0, 0], "max": [100, 100, 0],
         "sparse": {"count": 1, "indices": {"bufferView": 2, "componentType": 5121},
                    "values": {"bufferView": 3}}},
        {"bufferView": 1, "componentType": 5120, "normalized": True, "count": 3, "type": "VEC3"},
        {"bufferView": 4, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0], "max": [1]},
        {"bufferView": 5, "componentType": 5122, "normalized": True, "count": 2, "type": "VEC4"},
        {"bufferView": 6, "componentType": 5123, "count": 3, "type": "SCALAR"},
    ]
    doc = {
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_mesh_quantization"],
        "extensionsRequired": ["KHR_mesh_quantization"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "arm", "children": [1]},
                  {"name": "prop", "mesh": 0, "translation": [0.5, 0, 0],
                   "scale": [0.01, 0.01, 0.01]}],
        "meshes": [{"name": "plate", "primitives": [{"attributes": {
            "POSITION": 0, "NORMAL": 1}, "indices": 4}]}],
        "animations": [{"name": "swing", "samplers": [
            {"input": 2, "output": 3, "interpolation": "LINEAR"}],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "rotation"}}]}],
        "accessors": acc,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
    }
    write("gltf_fuzzer", "rigid_quantized_sparse.gltf", json.dumps(doc).encode())


def response_seeds():
    # RawPart's inputs: a first byte choosing the slice length, then a SkinResponse.
    def part(slice_byte, text):
        return bytes([slice_byte]) + encode("SkinResponse", text)

    timing = "timing { queued_ns: 1000 compute_ns: 52000 encode_ns: 7000 }"
    write("raw_part_fuzzer", "float32_normals",
          part(6, f'frame: 3 vertex_count: 2 total_vertices: 2 last: true instances: 1 '
                  f'positions: "{octal(floats([1, 2, 3, -4, 5, 6.5]))}" '
                  f'normals: "{octal(floats([0, 0, 1, 0, 1, 0]))}" {timing}'))
    q = struct.pack("<12h", -32767, 0, 32767, 100, -100, 5, 1, 2, 3, 4, 5, 6)
    write("raw_part_fuzzer", "snorm16_packed",
          part(16, f'frame: 9 vertex_count: 2 total_vertices: 2 last: true instances: 2 '
                   f'instance_count: 2 encoding: ENCODING_SNORM16 positions: "{octal(q)}" '
                   f'bounds {{ min_x: -1 min_y: -1 min_z: -1 max_x: 1 max_y: 2 max_z: 3 }} '
                   f'instance_bounds {{ min_x: -1 min_y: -1 min_z: -1 max_x: 1 max_y: 2 max_z: 3 }} '
                   f'instance_bounds {{ min_x: 0 min_y: 0 min_z: 0 max_x: 4 max_y: 4 max_z: 4 }} '
                   f'{timing}'))
    write("raw_part_fuzzer", "error",
          part(3, 'frame: 4 last: true error { code: 3 message: "instance 2: palette" }'))
    # The vertex fields before the header, and a field given twice (the last one counts).
    header = encode("SkinResponse", f"frame: 5 vertex_count: 1 total_vertices: 1 {timing}")
    first = encode("SkinResponse", f'positions: "{octal(floats([9, 9, 9]))}"')
    second = encode("SkinResponse", f'positions: "{octal(floats([1, 2, 3]))}"')
    write("raw_part_fuzzer", "reordered", bytes([1]) + first + second + header)


if __name__ == "__main__":
    upload_seeds()
    request_seeds()
    gltf_seed()
    gltf_rigid_quantized_seed()
    response_seeds()
