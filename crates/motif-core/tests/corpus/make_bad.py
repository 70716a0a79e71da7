#!/usr/bin/env python3
"""Writes the bad-input corpus in ./bad (run from anywhere; the files are committed).

Every file here must make motif_core::io::read fail with Error::Parse naming the file and a
position, without panicking and without allocating by the counts it claims. tests/io.rs checks
that, and the table EXPECT there says which message and position each file must give.
"""
import base64
import json
import os
import struct

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "bad")
os.makedirs(HERE, exist_ok=True)


def put(name, data):
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(data)


PLY_XYZ = "property float x\nproperty float y\nproperty float z\n"
TRI = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]

# --- empty files of every extension
for ext in ["obj", "ply", "off", "stl", "gltf", "glb"]:
    put(f"empty.{ext}", b"")

# --- PLY
head = "ply\nformat binary_little_endian 1.0\nelement vertex 3\n" + PLY_XYZ + \
       "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
body = b"".join(struct.pack("<3f", *p) for p in TRI) + struct.pack("<B3i", 3, 0, 1, 2)
put("ply_truncated_binary.ply", head.encode() + body[:-5])
put("ply_wrong_magic.ply", "plx\nformat ascii 1.0\nelement vertex 0\nend_header\n")
put("ply_vertex_count_4e9.ply",
    "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n" + PLY_XYZ + "end_header\n" + "\0" * 24)
put("ply_face_count_huge.ply",
    "ply\nformat ascii 1.0\nelement vertex 3\n" + PLY_XYZ +
    "element face 3000000000\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
# A list of an unknown element whose count runs past the end of the file.
put("ply_list_count_past_end.ply",
    ("ply\nformat binary_little_endian 1.0\nelement vertex 3\n" + PLY_XYZ +
     "element material 1\nproperty list int float values\nend_header\n").encode()
    + b"".join(struct.pack("<3f", *p) for p in TRI) + struct.pack("<i", 2_000_000_000) + b"\0" * 8)
put("ply_index_out_of_range.ply",
    "ply\nformat ascii 1.0\nelement vertex 3\n" + PLY_XYZ +
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n")
put("ply_nan.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + PLY_XYZ + "end_header\n0 0 0\n1 nan 0\n0 1 0\n")
put("ply_binary_inf.ply",
    ("ply\nformat binary_big_endian 1.0\nelement vertex 2\n" + PLY_XYZ + "end_header\n").encode()
    + struct.pack(">3f", 0, 0, 0) + struct.pack(">3f", 0, float("inf"), 0))
put("ply_no_end_header.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + PLY_XYZ)
put("ply_unknown_type.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n0\n")
put("ply_non_utf8_header.ply", b"ply\nformat ascii 1.0\nelement vert\xe9x 1\n" + PLY_XYZ.encode() + b"end_header\n0 0 0\n")
put("ply_all_degenerate.ply",
    "ply\nformat ascii 1.0\nelement vertex 3\n" + PLY_XYZ +
    "element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 0 1\n2 1 2\n")

# --- OBJ
put("obj_index_out_of_range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n")
put("obj_nan.obj", "v 0 0 0\nv 1 NaN 0\nv 0 1 0\nf 1 2 3\n")
put("obj_inf.obj", "v 0 0 0\nv 1 0 0\nv 0 1 -inf\nf 1 2 3\n")
put("obj_non_utf8.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\no caf\xe9\nf 1 2 3\n")
put("obj_non_utf8_number.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 \xff\nf 1 2 3\n")
put("obj_index_zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
put("obj_relative_before_start.obj", "v 0 0 0\nv 1 0 0\nf -1 -2 -3\n")
put("obj_all_degenerate.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 1 2\nf 2 3\n")
put("obj_bad_corner.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1/1 2 3\n")
put("obj_short_vertex.obj", "v 0 0 0\nv 1 0\n")
put("obj_no_vertices.obj", "# only a comment\n\n")

# --- OFF
put("off_counts_larger_than_file.off", "OFF\n1000 2000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
put("off_truncated_faces.off", "OFF\n3 3 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 2 1\n")
put("off_index_out_of_range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")
put("off_4off.off", "4OFF\n3 1 0\n0 0 0 1\n1 0 0 1\n0 1 0 1\n3 0 1 2\n")
put("off_binary.off", "OFF BINARY\n" + "\0" * 16)
put("off_nan.off", "OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n")
put("off_wrong_header.off", "ply\nformat ascii 1.0\n")
put("off_face_short.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n")

# --- STL
def stl_binary(tris, header=b"bad corpus"):
    out = header.ljust(80, b"\0") + struct.pack("<I", len(tris))
    for t in tris:
        out += struct.pack("<3f", 0, 0, 1) + b"".join(struct.pack("<3f", *c) for c in t) + b"\0\0"
    return out


good = stl_binary([TRI, [(1, 0, 0), (1, 1, 0), (0, 1, 0)]])
put("stl_binary_truncated.stl", good[:-30])
put("stl_binary_truncated_solid_header.stl", stl_binary([TRI, TRI], b"solid but binary")[:-1])
put("stl_binary_count_huge.stl", good[:80] + struct.pack("<I", 4_000_000_000) + good[84:])
put("stl_binary_nan.stl", stl_binary([[(0, 0, 0), (float("nan"), 0, 0), (0, 1, 0)]]))
put("stl_too_short.stl", b"\x01\x02\x03 not an stl")
put("stl_ascii_truncated.stl",
    "solid t\n  facet normal 0 0 1\n    outer loop\n      vertex 0 0 0\n      vertex 1 0 0\n")
put("stl_ascii_bad_keyword.stl",
    "solid t\n  facet normal 0 0 1\n    outer loop\n      vertex 0 0 0\n      vortex 1 0 0\n")
put("stl_ascii_all_degenerate.stl",
    "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid t\n")


# --- glTF / GLB
def glb(doc, bin_chunk):
    return glb_raw(json.dumps(doc).encode(), bin_chunk)


def glb_raw(js, bin_chunk):
    js += b" " * (-len(js) % 4)
    bin_chunk += b"\0" * (-len(bin_chunk) % 4)
    body = struct.pack("<I4s", len(js), b"JSON") + js + struct.pack("<I4s", len(bin_chunk), b"BIN\0") + bin_chunk
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


positions = b"".join(struct.pack("<3f", *p) for p in TRI)
indices = struct.pack("<3H", 0, 1, 2) + b"\0\0"


def doc(count=3, index_values_view=1, byte_length=None, uri=None):
    buf = {"byteLength": byte_length if byte_length is not None else len(positions) + len(indices)}
    if uri is not None:
        buf["uri"] = uri
    return {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [buf],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": len(positions)},
            {"buffer": 0, "byteOffset": len(positions), "byteLength": 6},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC3",
             "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": index_values_view, "componentType": 5123, "count": 3, "type": "SCALAR"},
        ],
    }


ok = glb(doc(), positions + indices)
put("glb_wrong_magic.glb", b"gLTF" + ok[4:])
put("glb_accessor_out_of_bounds.glb", glb(doc(count=1000), positions + indices))
put("glb_accessor_count_huge.glb", glb(doc(count=4_000_000_000), positions + indices))
put("glb_truncated.glb", ok[:-10])
put("glb_index_out_of_range.glb", glb(doc(), positions + struct.pack("<3H", 0, 1, 9) + b"\0\0"))
put("glb_version_1.glb", ok[:4] + struct.pack("<I", 1) + ok[8:])
put("glb_bad_json.glb", glb_raw(b'{"asset": {"version": "2.0"}, not json}', b""))
nan_positions = struct.pack("<3f", 0, 0, 0) + struct.pack("<3f", float("nan"), 0, 0) + struct.pack("<3f", 0, 1, 0)
put("glb_nan.glb", glb(doc(), nan_positions + indices))
put("gltf_bad_json.gltf", '{\n  "asset": {"version": "2.0"},\n  "scenes": [,]\n}\n')
put("gltf_escaping_uri.gltf", json.dumps(doc(uri="../outside.bin"), indent=1))
put("gltf_missing_buffer_file.gltf", json.dumps(doc(uri="no_such_file.bin"), indent=1))
put("gltf_index_out_of_range.gltf", json.dumps(
    doc(uri="data:application/octet-stream;base64,"
        + base64.b64encode(positions + struct.pack("<3H", 0, 1, 5) + b"\0\0").decode()), indent=1))

# POSITION names an accessor that does not exist (gltf-json's validation indexes it unchecked)
put("gltf_position_accessor_missing.gltf",
    '{"asset": {"version": "2.0"}, "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}]}\n')

# a major version this reader does not know (glTF 2.0, 5.1: must not be loaded)
put("gltf_version_3.gltf", '{"asset": {"version": "3.0"}}\n')

print(f"wrote {len(os.listdir(HERE))} files to {HERE}")
