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
    write("graphs/stub_chain.json",
          '{"seed": 7, "catalog": "{corpus}/catalogs/tiny/catalog.json", "model_cache": "{tmp}/model.fhm",\n'
          ' "training": {"sensor": "sim"},\n "stages": {\n'
          '  "sim": {"type": "sensors.simulated_laser", "params": {"views": 2, "angular_resolution_deg": 2,'
          ' "tilt_resolution_deg": 2}},\n'
          '  "input": {"type": "sensors.scan_file"},\n'
          '  "seg": {"type": "segmenters.hostile_stub", "inputs": ["input"]},\n'
          '  "feat": {"type": "features.centroid", "inputs": ["seg"]},\n'
          '  "vote": {"type": "voters.hostile_stub", "inputs": ["feat"]}}}\n')

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
