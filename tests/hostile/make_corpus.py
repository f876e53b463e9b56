#!/usr/bin/env python3
"""Writes the hostile-input corpus (tests/hostile/corpus/) and the fuzz seeds
(tests/fuzz/corpus/<target>/). The files are committed; this script documents how each was
made and rebuilds them: python3 tests/hostile/make_corpus.py

Files named fuzz_* are inputs the fuzz targets (tests/fuzz) found, copied here by hand once
fixed (without the scan target's leading format byte). Inputs too big to commit (10^7
points) or that cannot live in git (FIFOs, folders, deep nesting) are made at test time by
test_hostile.cpp.
"""
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))
CORPUS = os.path.join(HERE, "corpus")
SEEDS = os.path.join(HERE, "..", "fuzz", "corpus")


def write(rel, data, root=CORPUS):
    path = os.path.join(root, rel)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "wb") as f:
        f.write(data.encode() if isinstance(data, str) else data)


# ---- PCD -------------------------------------------------------------------------------
def pcd_header(n, data, fields="x y z", size="4 4 4", type_="F F F", count="1 1 1", width=None,
               height=1, points=None):
    return ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS %s\nSIZE %s\nTYPE %s\n"
            "COUNT %s\nWIDTH %s\nHEIGHT %s\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %s\nDATA %s\n" %
            (fields, size, type_, count, n if width is None else width, height,
             n if points is None else points, data))


def pcd_ascii(pts, **kw):
    return pcd_header(len(pts), "ascii", **kw) + "".join("%r %r %r\n" % p for p in pts)


def pcd_binary(pts, **kw):
    return pcd_header(len(pts), "binary", **kw).encode() + b"".join(struct.pack("<3f", *p) for p in pts)


def lzf_literal(raw):
    """LZF stream of literal runs only (control byte < 32: copy the next ctrl + 1 bytes)."""
    out = bytearray()
    for i in range(0, len(raw), 32):
        chunk = raw[i:i + 32]
        out.append(len(chunk) - 1)
        out += chunk
    return bytes(out)


def pcd_compressed(pts, compressed=None, uncompressed_size=None, compressed_size=None, **kw):
    # binary_compressed stores the fields one after the other (all x, all y, all z), LZF'ed.
    raw = b"".join(struct.pack("<%df" % len(pts), *[p[k] for p in pts]) for k in range(3))
    comp = lzf_literal(raw) if compressed is None else compressed
    head = pcd_header(len(pts), "binary_compressed", **kw).encode()
    return head + struct.pack("<II", len(comp) if compressed_size is None else compressed_size,
                              len(raw) if uncompressed_size is None else uncompressed_size) + comp


GOOD = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.5), (0.0, 1.0, 1.0), (1.0, 1.0, 1.5)]

# ---- PLY -------------------------------------------------------------------------------
def ply_header(fmt, n, props=("float x", "float y", "float z"), extra=""):
    return ("ply\nformat %s 1.0\nelement vertex %s\n" % (fmt, n) +
            "".join("property %s\n" % p for p in props) + extra + "end_header\n")


def ply_binary(pts, n=None, endian="<", fmt="binary_little_endian"):
    return ply_header(fmt, len(pts) if n is None else n).encode() + b"".join(
        struct.pack(endian + "3f", *p) for p in pts)


def ply_ascii(pts, n=None):
    return ply_header("ascii", len(pts) if n is None else n) + "".join("%r %r %r\n" % p for p in pts)


# ---- CBOR (enough of RFC 8949 for model files) ------------------------------------------
def cbor(v):
    def head(major, n):
        if n < 24:
            return bytes([major << 5 | n])
        for extra, fmt in ((24, ">B"), (25, ">H"), (26, ">I"), (27, ">Q")):
            if n < 1 << (8 * struct.calcsize(fmt)):
                return bytes([major << 5 | extra]) + struct.pack(fmt, n)
    if v is None:
        return b"\xf6"
    if v is True:
        return b"\xf5"
    if v is False:
        return b"\xf4"
    if isinstance(v, int):
        return head(0, v) if v >= 0 else head(1, -1 - v)
    if isinstance(v, float):
        return b"\xfb" + struct.pack(">d", v)
    if isinstance(v, str):
        b = v.encode()
        return head(3, len(b)) + b
    if isinstance(v, list):
        return head(4, len(v)) + b"".join(cbor(x) for x in v)
    if isinstance(v, dict):
        return head(5, len(v)) + b"".join(cbor(k) + cbor(x) for k, x in v.items())
    raise TypeError(v)


MAGIC = b"furnihost-model\n"
MODEL = {"format_version": 1, "training_config": {"seed": 42}, "catalog_hash": "0123456789abcdef",
         "voter_type": "voters.hostile_stub", "normaliser": {"min": [0.0, 0.0], "max": [1.0, 2.0]},
         "voter_model": {"stub_model": 1, "classes": {"cube": [0.5, 0.5]}}, "summary": {}}


def model(**changes):
    m = dict(MODEL)
    for k, v in changes.items():
        if v is None:
            m.pop(k)
        else:
            m[k] = v
    return MAGIC + cbor(m)


# ---- meshes ------------------------------------------------------------------------------
CUBE_OBJ = """# unit cube, 12 triangles
v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1
f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8
"""


# ---- meshes with bad face indices (issue 50): every format, every layout -----------------
TRI = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 1.0)]


def ply_mesh_binary(faces, endian="<", fmt="binary_little_endian", index="uint"):
    code = {"uint": "I", "int": "i", "ushort": "H"}[index]
    head = ("ply\nformat %s 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element face %d\nproperty list uchar %s vertex_indices\nend_header\n" % (fmt, len(faces), index))
    body = b"".join(struct.pack(endian + "3f", *v) for v in TRI)
    body += b"".join(struct.pack(endian + "B3" + code, 3, *f) for f in faces)
    return head.encode() + body


def gltf(indices, uri=None):
    """A one-triangle glTF 2.0: positions and uint16 indices, the buffer embedded or at `uri`."""
    import base64
    import json
    pos = b"".join(struct.pack("<3f", *v) for v in TRI)
    idx = struct.pack("<3H", *indices) + b"\x00\x00"
    data = pos + idx
    buf = {"byteLength": len(data),
           "uri": uri or "data:application/octet-stream;base64," + base64.b64encode(data).decode()}
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}], "buffers": [buf],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                           {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 1]},
                         {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}]}
    return json.dumps(doc), data


def dae(p="0 1 2", count=9):
    return ('<?xml version="1.0"?>\n<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">\n'
            '<asset><unit meter="1"/><up_axis>Z_UP</up_axis></asset>\n<library_geometries><geometry id="g"><mesh>\n'
            '<source id="p"><float_array id="pa" count="%d">0 0 0 1 0 0 0 1 1</float_array><technique_common>'
            '<accessor source="#pa" count="3" stride="3"><param name="X" type="float"/><param name="Y" type="float"/>'
            '<param name="Z" type="float"/></accessor></technique_common></source>\n'
            '<vertices id="v"><input semantic="POSITION" source="#p"/></vertices>\n'
            '<triangles count="1"><input semantic="VERTEX" source="#v" offset="0"/><p>%s</p></triangles>\n'
            '</mesh></geometry></library_geometries>\n<library_visual_scenes><visual_scene id="s"><node id="n">'
            '<instance_geometry url="#g"/></node></visual_scene></library_visual_scenes>\n'
            '<scene><instance_visual_scene url="#s"/></scene>\n</COLLADA>\n' % (count, p))


# The detection chain of the test-only stubs (its closing braces left to the graph that uses it).
STUB_CHAIN = ('{"seed": 7, "catalog": "{corpus}/catalogs/tiny/catalog.json", "model_cache": "{tmp}/model.fhm",\n'
              ' "training": {"sensor": "sim"},\n "stages": {\n'
              '  "sim": {"type": "sensors.simulated_laser", "params": {"views": 2, "angular_resolution_deg": 2,'
              ' "tilt_resolution_deg": 2}},\n'
              '  "input": {"type": "sensors.scan_file"},\n'
              '  "seg": {"type": "segmenters.hostile_stub", "inputs": ["input"]},\n'
              '  "feat": {"type": "features.centroid", "inputs": ["seg"]},\n'
              '  "vote": {"type": "voters.hostile_stub", "inputs": ["feat"]}')


def catalog(models):
    import json
    return json.dumps({"furnihost_catalog": 1, "models": models}, indent=1)


def entry(mesh, id_="cube", **kw):
    e = {"id": id_, "class": "cube", "mesh": mesh, "up": "+z"}
    e.update(kw or {"size_m": [0.5, 0.5, 0.6]})
    return e


SCENE = '{"room": {"size_m": [4, 4], "height_m": 2.5}, "objects": [{"model": "cube", "x": 1.5, "y": 2}],\n' \
        ' "sensors": [{"position": [3.2, 2, 1.2], "yaw_deg": 180, "pitch_deg": 20}],\n' \
        ' "sensor_params": {"angular_resolution_deg": 2, "tilt_resolution_deg": 2, "noise_a": 0, "noise_b": 0}}\n'


def main():
    # -- scans
    for ext in ("pcd", "ply", "xyz"):
        write("scans/empty." + ext, b"")
    write("scans/one_point.pcd", pcd_binary([(1.0, 2.0, 0.5)]))
    write("scans/good.pcd", pcd_binary(GOOD))
    write("scans/pcd_header_only.pcd", pcd_header(10, "ascii"))
    write("scans/pcd_garbage_header.pcd", b"VERSION 0.7\nFIELDS \x00\xff\xfe\nDATA binary\n\x01\x02")
    write("scans/pcd_truncated_binary.pcd", pcd_header(1000, "binary").encode() + b"\x00" * 12)
    write("scans/pcd_truncated_compressed.pcd", pcd_compressed(GOOD)[:-20])
    write("scans/pcd_compressed_sizes_lie.pcd", pcd_compressed(GOOD, compressed_size=100000))
    write("scans/pcd_compressed_huge_uncompressed.pcd", pcd_compressed(GOOD, uncompressed_size=0xFFFFFFF0))
    write("scans/pcd_compressed_corrupt_stream.pcd",
          pcd_compressed(GOOD, compressed=bytes([0xE0, 0xFF, 0xFF]) + b"\x1f" + b"\x00" * 40))
    write("scans/pcd_compressed_zero_sizes.pcd", pcd_compressed(GOOD, compressed=b"", uncompressed_size=0))
    write("scans/pcd_negative_width.pcd", pcd_header(4, "binary", width=-5).encode() + b"\x00" * 48)
    write("scans/pcd_huge_dims.pcd", pcd_header(4, "binary", width=4294967295, height=4294967295,
                                                points=4294967295).encode() + b"\x00" * 48)
    write("scans/pcd_points_above_cap.pcd", pcd_header(4, "binary", width=50000000, points=50000000).encode() +
          b"\x00" * 48)
    write("scans/pcd_field_count_mismatch.pcd", pcd_header(4, "ascii", size="4 4") + "1 2 3\n" * 4)
    write("scans/pcd_int_fields.pcd", pcd_ascii([(1, 2, 3)] * 4, type_="I I I"))
    write("scans/pcd_no_xyz.pcd", pcd_ascii(GOOD, fields="a b c"))
    write("scans/pcd_zero_sizes.pcd", pcd_header(4, "binary", size="0 0 0").encode() + b"\x00" * 48)
    write("scans/pcd_unknown_data.pcd", pcd_header(4, "zipped").encode() + b"\x00" * 48)
    write("scans/pcd_all_nan.pcd", pcd_ascii([(math.nan,) * 3, (math.inf, 0.0, 0.0), (0.0, -math.inf, 1.0)]))
    write("scans/pcd_1e30.pcd", pcd_binary([(1e30, 1e30, 1e30), (-1e30, 5.0, 1.0), (3e38, 3e38, 3e38)]))
    write("scans/pcd_1e30_and_good.pcd", pcd_binary(GOOD + [(1e30, 0.0, 0.0), (0.0, 0.0, -1e30)]))
    # fuzz_scan_readers finding (issue 21): a second header inside the first, DATA
    # binary_compressed, made PCL's readBodyBinary read through a null pointer (SIGSEGV). The
    # own reader refuses a repeated keyword, and a header nested in the compressed body does
    # not decode to the declared size.
    inner = pcd_compressed(GOOD)
    write("scans/fuzz_pcd_nested_header.pcd", pcd_header(4, "binary_compressed").split("VIEWPOINT")[0].encode() + inner)
    write("scans/fuzz_pcd_nested_header_body.pcd",
          pcd_header(4, "binary_compressed").encode() + struct.pack("<II", 50, 48) + inner[:200])
    write("scans/ply_count_exceeds_data.ply", ply_binary(GOOD, n=1000))
    write("scans/ply_ascii_count_exceeds_data.ply", ply_ascii(GOOD, n=1000))
    write("scans/ply_negative_count.ply", ply_binary(GOOD, n=-3))
    write("scans/ply_count_overflow.ply", ply_binary(GOOD, n=18446744073709551615))
    write("scans/ply_count_above_cap.ply", ply_binary(GOOD, n=3000000000))
    write("scans/ply_wrong_type.ply",
          ply_header("binary_little_endian", 4, props=("float128 x", "float y", "float z")).encode() + b"\x00" * 64)
    write("scans/ply_list_vertex.ply",
          ply_header("ascii", 1, props=("list uchar int x", "float y", "float z")) + "1 5 0 0\n")
    write("scans/ply_no_end_header.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n")
    write("scans/ply_no_xyz.ply", ply_header("ascii", 1, props=("float a", "float b")) + "1 2\n")
    write("scans/ply_non_numeric.ply", ply_header("ascii", 2) + "1 2 3\nfour five six\n")
    write("scans/ply_unknown_format.ply", ply_header("binary_middle_endian", 4).encode() + b"\x00" * 48)
    write("scans/ply_element_before_vertex.ply",
          "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\n"
          "element vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
          "3 0 1 2\n0 0 0\n1 0 0\n0 1 0\n")
    write("scans/ply_uint_attribute.ply",
          ply_header("binary_little_endian", 2, props=("float x", "float y", "float z", "uint label")).encode() +
          struct.pack("<3fI", 1.0, 2.0, 0.5, 4294967295) + struct.pack("<3fI", 1.5, 2.0, 0.5, 7))
    write("scans/ply_all_nan.ply", ply_binary([(math.nan, 0.0, 0.0), (0.0, math.inf, 0.0)], endian=">",
                                              fmt="binary_big_endian"))
    write("scans/xyz_binary_garbage.xyz", bytes(range(256)) * 4)
    write("scans/xyz_all_nan.xyz", "nan nan nan\ninf 0 0\n0 -inf 0\n")
    write("scans/xyz_1e30.xyz", "1e30 0 0\n0 1e30 0\n0 0 -1e30\n")
    write("scans/unknown_ext.las", "LASF" + "\x00" * 100)

    # -- graphs (text with {tmp} / {corpus} placeholders is copied to the test's temp folder)
    write("graphs/read.json", '{"stages": {"input": {"type": "sensors.scan_file"}}}\n')
    write("graphs/read_capped.json",
          '{"limits": {"max_points": 1000000}, "stages": {"input": {"type": "sensors.scan_file"}}}\n')
    write("graphs/limit_below_param.json",
          '{"limits": {"max_points": 1000}, "stages": {"input": {"type": "sensors.scan_file",'
          ' "params": {"max_points": 5000}}}}\n')
    write("graphs/empty.json", b"")
    write("graphs/not_json.json", "{ stages: [ this is not json\n")
    write("graphs/nul_bytes.json", b'{"stages": {"in\x00put": {}}}')
    write("graphs/invalid_utf8.json", b'{"description": "\xff\xfe\xc3", "stages": {}}')
    write("graphs/huge_number.json", '{"seed": 1e400, "stages": {"input": {"type": "sensors.scan_file"}}}')
    write("graphs/top_level_array.json", "[1, 2, 3]\n")
    write("graphs/stages_array.json", '{"stages": ["input"]}\n')
    write("graphs/seed_string.json", '{"seed": "forty-two", "stages": {"input": {"type": "sensors.scan_file"}}}')
    write("graphs/seed_negative.json", '{"seed": -1, "stages": {"input": {"type": "sensors.scan_file"}}}')
    write("graphs/param_wrong_type.json",
          '{"stages": {"input": {"type": "sensors.scan_file", "params": {"voxel_m": "forty"}}}}')
    write("graphs/param_out_of_range.json",
          '{"stages": {"input": {"type": "sensors.scan_file", "params": {"voxel_m": 1e300}}}}')
    write("graphs/inputs_string.json",
          '{"stages": {"input": {"type": "sensors.scan_file"},'
          ' "f": {"type": "features.centroid", "inputs": "input"}}}')
    write("graphs/limits_wrong_type.json",
          '{"limits": {"max_points": "lots"}, "stages": {"input": {"type": "sensors.scan_file"}}}')
    write("graphs/threads_negative.json", '{"threads": -1, "stages": {"input": {"type": "sensors.scan_file"}}}')
    write("graphs/tag_with_slash.json", '{"stages": {"in/put~1": {"type": "sensors.scan_file"}}}')
    # fuzz_graph_config finding: std::regex_match overflowed the stack on a 32 kB stage tag.
    write("graphs/fuzz_long_stage_tag.json",
          '{"stages": {"' + "in2put" * 8000 + '/": {"type": "sensors.scan_file"}}}')
    write("graphs/unknown_plugin.json",
          '{"stages": {"input": {"type": "sensors.scan_file"}, "seg": {"type": "segmenters.nope",'
          ' "inputs": ["input"]}}}')
    write("graphs/unknown_input.json",
          '{"stages": {"input": {"type": "sensors.scan_file"}, "seg": {"type": "segmenters.hostile_stub",'
          ' "inputs": ["nothere"]}}}')
    chain = ('"input": {"type": "sensors.scan_file"}, "seg": {"type": "segmenters.hostile_stub", "inputs": ["input"]},'
             ' "feat": {"type": "features.centroid", "inputs": ["seg"]},'
             ' "vote": {"type": "voters.hostile_stub", "inputs": ["feat"]}, ')
    write("graphs/cycle.json",
          '{"catalog": "{corpus}/catalogs/tiny/catalog.json", "stages": {' + chain +
          '"a": {"type": "fitters.passthrough", "inputs": ["b"]},'
          ' "b": {"type": "fitters.passthrough", "inputs": ["a"]}}}')
    write("graphs/self_loop.json",
          '{"catalog": "{corpus}/catalogs/tiny/catalog.json", "stages": {' + chain +
          '"a": {"type": "fitters.passthrough", "inputs": ["a"]}}}')
    write("graphs/extends_missing.json", '{"extends": "nothere.json"}')
    write("graphs/extends_not_string.json", '{"extends": 42, "stages": {}}')
    write("graphs/extends_self.json", '{"extends": "extends_self.json"}')
    write("graphs/extends_loop_a.json", '{"extends": "extends_loop_b.json"}')
    write("graphs/extends_loop_b.json", '{"extends": "extends_loop_a.json"}')
    write("graphs/extends_directory.json", '{"extends": "."}')
    write("graphs/extends_not_json.json", '{"extends": "not_json.json"}')
    write("graphs/uses_refused_plugin.json",
          '{"stages": {"input": {"type": "sensors.scan_file"}, "f": {"type": "features.no_factory",'
          ' "inputs": ["seg"]}, "seg": {"type": "segmenters.hostile_stub", "inputs": ["input"]}}}')
    write("graphs/uses_throwing_plugin.json",
          '{"stages": {"input": {"type": "sensors.scan_file"}, "seg": {"type": "segmenters.throws",'
          ' "inputs": ["input"]}}}')
    write("graphs/uses_throwing_constructor.json",
          '{"stages": {"input": {"type": "sensors.scan_file"}, "seg": {"type": "segmenters.throws",'
          ' "inputs": ["input"], "params": {"throw_in_constructor": true}}}}')
    # The whole chain with the test-only stubs: trains from the tiny catalog in seconds.
    write("graphs/stub_chain.json", STUB_CHAIN + "}}\n")

    # -- catalogs (used through `furnihost simulate`)
    write("catalogs/tiny/cube.obj", CUBE_OBJ)
    write("catalogs/tiny/catalog.json", catalog([entry("cube.obj")]))
    write("catalogs/scene.json", SCENE)
    write("catalogs/not_json/catalog.json", "models: [cube]\n")
    write("catalogs/models_not_array/catalog.json", '{"models": {"cube": "cube.obj"}}')
    write("catalogs/missing_mesh/catalog.json", catalog([entry("nothere.obj")]))
    write("catalogs/mesh_is_directory/catalog.json", catalog([entry(".")]))
    write("catalogs/no_faces/points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n")
    write("catalogs/no_faces/catalog.json", catalog([entry("points.obj")]))
    # Every triangle has zero area (all vertices on one line): nothing to scan.
    write("catalogs/degenerate/line.obj", "v 0 0 0\nv 1 1 1\nv 2 2 2\nv 3 3 3\nf 1 2 3\nf 2 3 4\nf 1 1 1\n")
    write("catalogs/degenerate/catalog.json", catalog([entry("line.obj")]))
    write("catalogs/degenerate_flat/flat.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
    write("catalogs/degenerate_flat/catalog.json", catalog([entry("flat.obj")]))
    huge = "\n".join(" ".join(("1000000" if t == "0" else "2000000" if t == "1" else t)
                              for t in l.split()) if l.startswith("v ") else l for l in CUBE_OBJ.splitlines()) + "\n"
    write("catalogs/huge_units/huge.obj", huge)
    write("catalogs/huge_units/catalog.json", catalog([entry("huge.obj", scale=1.0)]))
    # The same 10^6-unit mesh with a size: normalised to metres, must simulate fine.
    write("catalogs/huge_units_sized/huge.obj", huge)
    write("catalogs/huge_units_sized/catalog.json", catalog([entry("huge.obj")]))
    write("catalogs/nan_vertex/nan.obj", CUBE_OBJ.replace("v 1 1 1", "v nan 1 inf"))
    write("catalogs/nan_vertex/catalog.json", catalog([entry("nan.obj")]))
    write("catalogs/bad_face_index/bad.obj", CUBE_OBJ + "f 1 2 99\n")
    write("catalogs/bad_face_index/catalog.json", catalog([entry("bad.obj")]))
    write("catalogs/bad_face_index_ply/bad.ply",
          "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
          "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
          "0 0 0\n1 0 0\n0 1 1\n3 0 1 2\n3 0 1 99\n")
    write("catalogs/bad_face_index_ply/catalog.json", catalog([entry("bad.ply")]))
    write("catalogs/garbage_mesh/junk.obj", bytes(range(256)) * 8)
    write("catalogs/garbage_mesh/catalog.json", catalog([entry("junk.obj")]))
    # Binary STL: 80-byte header, then a triangle count far beyond the file's size.
    write("catalogs/stl_count_lies/lies.stl", b"\x00" * 80 + struct.pack("<I", 100000000) + b"\x00" * 50)
    write("catalogs/stl_count_lies/catalog.json", catalog([entry("lies.stl")]))
    # fuzz_catalog finding: a control byte merges an OFF vertex line with a face line; assimp's
    # triangulation then fails an internal assertion, which aborts in Debian's (debug) build.
    write("catalogs/fuzz_off_assert/broken.off", b"OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 1\x063 0 1 2\n3 0 2 3\n")
    write("catalogs/fuzz_off_assert/catalog.json", catalog([entry("broken.off", up="+y", height_m=0.7)]))
    # fuzz_catalog finding: assimp's PLY importer never returns on a header without end_header.
    write("catalogs/fuzz_ply_no_end_header/truncated.ply",
          "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n")
    write("catalogs/fuzz_ply_no_end_header/catalog.json", catalog([entry("truncated.ply")]))
    # fuzz_catalog finding (issue 21 run): "ply" and garbage on the first line; assimp takes the
    # file for PLY by its token and never returns.
    write("catalogs/fuzz_ply_garbage_magic/garbage.ply",
          b"ply\xb4\xb4\xb4\xb4\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
          b"properx 0 1 1\nendloop\nendfacet\nendsolid t\n")
    write("catalogs/fuzz_ply_garbage_magic/catalog.json", catalog([entry("garbage.ply")]))
    # fuzz_catalog finding: assimp's OFF importer reads vertices by unchecked face indices
    # (heap overflow, then a crash under ASan or with a far index).
    write("catalogs/fuzz_off_index/far.off", "OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 1\n3 0 1 2\n3 5 2 3\n")
    write("catalogs/fuzz_off_index/catalog.json", catalog([entry("far.off", up="+y", height_m=0.7)]))
    # fuzz_catalog finding: ... and on a header line it cannot parse.
    write("catalogs/fuzz_ply_bad_header/garbled.ply",
          b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n{\nproperty float y\nproperty float z\n"
          b"element face 1\nproperty list uchar int ve \"furn47\x0c\x00\"z [\nend_header\n0 0 0\n1 0 0\n0 1 1\n3 0 1 2\n")
    write("catalogs/fuzz_ply_bad_header/catalog.json", catalog([entry("garbled.ply")]))
    # fuzz_catalog finding: "OFF<digits>" made assimp allocate 50 GB (std::bad_alloc, or the
    # OOM killer).
    write("catalogs/fuzz_off_header_count/huge.off", "OFF66666666666666666666666666\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 1\n"
          "3 0 1 2\n3 0 2 3\n")
    write("catalogs/fuzz_off_header_count/catalog.json", catalog([entry("huge.off", up="+y", height_m=0.7)]))
    write("catalogs/bad_scale/catalog.json", catalog([entry("../tiny/cube.obj", scale=-1)]))
    write("catalogs/overflow_scale/catalog.json", catalog([entry("../tiny/cube.obj", scale=1e300)]))

    # -- issue 50: face indices past the vertices, in every format and layout (assimp's
    # post-processing follows them unchecked: SIGSEGV before the raw-scene check)
    write("catalogs/ply_binary_face_index/bad.ply", ply_mesh_binary([(0, 1, 2), (0, 1, 0xFFFFFFF0)]))
    write("catalogs/ply_binary_face_index/catalog.json", catalog([entry("bad.ply")]))
    write("catalogs/ply_big_endian_face_index/bad.ply",
          ply_mesh_binary([(0, 1, 0x7FFFFFF0), (0, 1, 2)], endian=">", fmt="binary_big_endian", index="int"))
    write("catalogs/ply_big_endian_face_index/catalog.json", catalog([entry("bad.ply")]))
    write("catalogs/ply_face_after_other_element/bad.ply",
          "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
          "element edge 1\nproperty int vertex1\nproperty int vertex2\n"
          "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
          "0 0 0\n1 0 0\n0 1 1\n0 1\n3 0 1 2\n3 0 1 70000\n")
    write("catalogs/ply_face_after_other_element/catalog.json", catalog([entry("bad.ply")]))
    write("catalogs/ply_face_before_vertex/bad.ply",
          "ply\nformat ascii 1.0\nelement face 2\nproperty list uchar int vertex_indices\n"
          "element vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
          "3 0 1 2\n4 0 1 2 4000000000\n0 0 0\n1 0 0\n0 1 1\n")
    write("catalogs/ply_face_before_vertex/catalog.json", catalog([entry("bad.ply")]))
    write("catalogs/obj_negative_index/bad.obj", CUBE_OBJ + "f -1 -2 -99\n")
    write("catalogs/obj_negative_index/catalog.json", catalog([entry("bad.obj")]))
    write("catalogs/gltf_face_index/bad.gltf", gltf((0, 1, 999))[0])
    write("catalogs/gltf_face_index/catalog.json", catalog([entry("bad.gltf")]))
    write("catalogs/dae_face_index/bad.dae", dae("0 1 99"))
    write("catalogs/dae_face_index/catalog.json", catalog([entry("bad.dae")]))
    # The same, well-formed: the checks refuse only what is broken.
    write("catalogs/gltf_good/good.gltf", gltf((0, 1, 2))[0])
    write("catalogs/gltf_good/catalog.json", catalog([entry("good.gltf")]))
    write("catalogs/dae_good/good.dae", dae())
    write("catalogs/dae_good/catalog.json", catalog([entry("good.dae")]))
    # Counts beyond the file: 2e9 faces declared by a 300-byte PLY (assimp: std::bad_alloc).
    write("catalogs/ply_2e9_faces/huge.ply",
          "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
          "property float z\nelement face 2000000000\nproperty list uchar int vertex_indices\nend_header\n".encode() +
          b"".join(struct.pack("<3f", *v) for v in TRI) + struct.pack("<B3i", 3, 0, 1, 2))
    write("catalogs/ply_2e9_faces/catalog.json", catalog([entry("huge.ply")]))
    write("catalogs/dae_2e9_values/huge.dae", dae(count=2000000000))
    write("catalogs/dae_2e9_values/catalog.json", catalog([entry("huge.dae")]))

    # -- issue 50: XYZ text as it comes (decimal commas, semicolons, BOMs, UTF-16, counts)
    write("scans/xyz_semicolon_decimal_comma.xyz", "1,250;2,500;0,750\n1,5;2;0,5\n-0,25;1,75;2,125\n")
    write("scans/xyz_blank_decimal_comma.xyz", "1,250 2,500 0,750\n1,5\t2\t0,5\n")
    write("scans/xyz_semicolon_then_comma_list.xyz", "1,0;2,0;3,0\n1,2,3\n")
    write("scans/xyz_comma_then_semicolon.xyz", "1,2,3\n4;5;6\n")
    write("scans/xyz_two_points_on_a_line.xyz", "0 0 0\n1 1 1 2 2 2\n")
    write("scans/xyz_100_values_on_a_line.xyz", " ".join(str(i % 7) for i in range(100)) + "\n")
    write("scans/xyz_utf16le_bom.xyz", "\ufeff1 2 3\n4 5 6\n".encode("utf-16-le"))
    write("scans/xyz_utf16be_bom.xyz", "\ufeff1 2 3\n4 5 6\n".encode("utf-16-be"))
    write("scans/xyz_utf16le_no_bom.xyz", "1 2 3\n4 5 6\n".encode("utf-16-le"))
    write("scans/xyz_utf8_bom.xyz", "\ufeff1 2 3\n4 5 6\n7 8 9\n".encode("utf-8"))
    write("scans/leica_count_line.pts", "3\n0 0 0 -1200 255 0 0\n1 0 0 -1100 0 255 0\n0 1 1 -900 0 0 255\n")
    write("scans/leica_two_scans.pts", "2\n0 0 0 10 1 2 3\n1 0 0 10 1 2 3\n2\n0 1 1 10 1 2 3\n1 1 1 10 1 2 3\n")
    # A float colour channel holding NaN (what fuzz_ply_nan_colour.ply found, in a header that
    # is otherwise well-formed): colour 0, never a cast of NaN to a byte.
    write("scans/ply_nan_colour.ply",
          ply_header("binary_little_endian", 2, props=("float x", "float y", "float z", "float red", "float green",
                                                        "float blue")).encode() +
          struct.pack("<6f", 1.0, 2.0, 0.5, math.nan, 3.0, math.inf) + struct.pack("<6f", 1.5, 2.0, 0.5, 1.0, 2.0, 3.0))
    write("scans/ply_two_vertex_elements.ply",
          "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
          "element vertex 2\nproperty float nx\nend_header\n0 0 0\n1 1 1\n0\n1\n")
    # binary_compressed declaring 4 GB uncompressed in 600 bytes: refused by the ratio LZF allows.
    write("scans/pcd_compressed_declares_4gb.pcd",
          pcd_compressed(GOOD, uncompressed_size=4095 * 1048576, fields="x y z d", size="4 4 4 4",
                         type_="F F F F", count="1 1 1 262141", width=4095, points=4095))
    # ... and the point cap holds for binary_compressed too (header only: refused before the data).
    write("scans/pcd_compressed_above_cap.pcd", pcd_compressed(GOOD, width=5000, points=5000))
    write("graphs/read_cap1000.json",
          '{"limits": {"max_points": 1000}, "stages": {"input": {"type": "sensors.scan_file"}}}\n')
    # Stages without a model: parts (region growing, paper24) and object proposals (clusters,
    # a height-map ground): what long runs along an axis and stray returns go through.
    write("graphs/parts_only.json",
          '{"stages": {"input": {"type": "sensors.scan_file"},\n'
          ' "seg": {"type": "segmenters.region_growing", "inputs": ["input"]},\n'
          ' "feat": {"type": "features.paper24", "inputs": ["seg"]}}}\n')
    write("graphs/proposals_only.json",
          '{"ground": {"kind": "height_map"}, "stages": {"input": {"type": "sensors.scan_file"},\n'
          ' "prop": {"type": "proposals.clusters", "inputs": ["input"], "params": {"wall_normals": "both",\n'
          ' "wall_voxel_m": 0.08, "blocks_rules": "segs", "thin_spacing_m": 0.013}}}}\n')
    # The stub chain with the real fitter: occupancy grids from the sensor origin.
    write("graphs/stub_fit_chain.json", STUB_CHAIN + ',\n  "fit": {"type": "fitters.ransac_upright", "inputs": ["vote"]}}}\n')

    # -- model files
    good = model()
    write("models/bad_magic.fhm", b"not-a-model\n" + good[len(MAGIC):])
    write("models/magic_only.fhm", MAGIC)
    write("models/truncated.fhm", good[:len(good) // 2])
    write("models/garbage_cbor.fhm", MAGIC + bytes([0xff, 0x5b, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff]))
    write("models/wrong_version.fhm", model(format_version=99))
    write("models/missing_field.fhm", model(normaliser=None))
    write("models/wrong_field_type.fhm", model(normaliser={"min": "x", "max": [1.0]}))
    write("models/normaliser_mismatch.fhm", model(normaliser={"min": [0.0], "max": [1.0, 2.0]}))
    write("models/huge_declared_string.fhm", MAGIC + b"\xa1\x7b" + struct.pack(">Q", 1 << 62) + b"abc")

    # -- fuzz seeds (first byte of a scan seed picks .pcd / .ply / .xyz)
    write("scan_readers/pcd_ascii", b"\x00" + pcd_ascii(GOOD).encode(), SEEDS)
    write("scan_readers/pcd_binary", b"\x00" + pcd_binary(GOOD), SEEDS)
    write("scan_readers/pcd_compressed", b"\x00" + pcd_compressed(GOOD), SEEDS)
    write("scan_readers/ply_ascii", b"\x01" + ply_ascii(GOOD).encode(), SEEDS)
    write("scan_readers/ply_le", b"\x01" + ply_binary(GOOD), SEEDS)
    write("scan_readers/ply_be", b"\x01" + ply_binary(GOOD, endian=">", fmt="binary_big_endian"), SEEDS)
    write("scan_readers/xyz", b"\x02" + b"0 0 0\n1,2,3\n# c\n4;5;6 7\n", SEEDS)
    write("model_file/good", good, SEEDS)
    write("model_file/wrong_version", model(format_version=3), SEEDS)
    write("graph_config/chain",
          '{"seed": 3, "catalog": "c.json", "model_cache": "m.fhm", "limits": {"max_points": 100},\n'
          ' "training": {"sensor": "sim"}, "stages": {"sim": {"type": "sensors.simulated_laser"},\n'
          ' "input": {"type": "sensors.scan_file", "params": {"voxel_m": 0.1, "origin": [0, 0, 1]}},\n'
          ' "feat": {"type": "features.centroid", "inputs": ["input"]},\n'
          ' "a": {"type": "fitters.passthrough", "inputs": ["b"]}, "b": {"type": "fitters.passthrough"}}}', SEEDS)
    write("graph_config/extends",
          '{"extends": "base.json", "stages": {"input": {"params": {"voxel_m": null}}}}\n---\n'
          '{"extends": "base2.json", "seed": 1, "stages": {"input": {"type": "sensors.scan_file"}}}\n---\n'
          '{"description": "x", "stages": {"f": {"type": "features.outside_example", "inputs": ["input"],'
          ' "params": {"scale": 2}}}}', SEEDS)
    write("graph_config/presets",
          '{"catalog": "c.json", "training": {"sensor": "sim"}, "stages": {"input": {"type": "sensors.scan_file"},\n'
          ' "sim": {"type": "sensors.simulated_laser", "params": {"preset": "mine", "holes": 0.2,\n'
          ' "presets": {"mine": {"pattern": "depth_camera", "flying_pixels": 0.5, "views": 2},\n'
          ' "room_reconstruction": {"fuse": 2}}}},\n'
          ' "feat": {"type": "features.centroid", "inputs": ["input"]}}}', SEEDS)
    # -- mesh seeds (tests/fuzz/fuzz_mesh.cpp: the first byte picks .ply .obj .gltf .dae .glb; then
    # the mesh, and after "\n---\n" lines m.mtl and m.bin)
    tri_ply_ascii = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                     "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 1\n3 0 1 2\n")
    write("mesh/ply_ascii", b"\x00" + tri_ply_ascii.encode(), SEEDS)
    write("mesh/ply_binary", b"\x00" + ply_mesh_binary([(0, 1, 2)]), SEEDS)
    write("mesh/obj_mtl", b"\x01" + ("mtllib m.mtl\nusemtl red\n" + CUBE_OBJ +
                                     "\n---\nnewmtl red\nKd 1 0 0\n").encode(), SEEDS)
    doc, data = gltf((0, 1, 2), uri="m.bin")
    write("mesh/gltf_external", b"\x02" + doc.encode() + b"\n---\n\n---\n" + data, SEEDS)
    write("mesh/gltf_embedded", b"\x02" + gltf((0, 1, 2))[0].encode(), SEEDS)
    write("mesh/dae", b"\x03" + dae().encode(), SEEDS)
    doc, data = gltf((0, 1, 2), uri=None)
    js = doc.replace('"uri": "data:application/octet-stream;base64,', '"x": "').encode()
    js += b" " * ((4 - len(js) % 4) % 4)
    glb = b"glTF" + struct.pack("<II", 2, 12 + 8 + len(js) + 8 + len(data)) + struct.pack("<I", len(js)) + b"JSON" + js
    glb += struct.pack("<I", len(data)) + b"BIN\x00" + data
    write("mesh/glb", b"\x04" + glb, SEEDS)
    # -- command-line JSON seeds (tests/fuzz/fuzz_cli_json.cpp: the text of one value)
    write("cli_json/number", "0.05", SEEDS)
    write("cli_json/array", "[0, 0, 1.5]", SEEDS)
    write("cli_json/object", '{"preset": "room_reconstruction", "views": 4, "holes": 0.1}', SEEDS)
    write("cli_json/presets", '{"mine": {"pattern": "depth_camera", "flying_pixels": 0.5}}', SEEDS)
    write("cli_json/bare_word", "height_map", SEEDS)
    write("cli_json/nested", "[[[[[[[[{\"a\": [1e400]}]]]]]]]]", SEEDS)
    write("catalog/all_formats",
          catalog([entry("a.obj", "a"), entry("b.off", "b", up="+y", height_m=0.7),
                   entry("c.ply", "c", scale=0.01), entry("d.stl", "d", up="-x")]) + "\n---\n" + CUBE_OBJ +
          "\n---\nOFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 1\n3 0 1 2\n3 0 2 3\n" +
          "\n---\nply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
          "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 1\n3 0 1 2\n" +
          "\n---\nsolid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 1\nendloop\n"
          "endfacet\nendsolid t\n", SEEDS)


if __name__ == "__main__":
    main()
