#!/usr/bin/env python3
"""Writes the hand-made seeds of the glTF and environment-image fuzz corpora.

    python3 tests/fuzz/make_seeds.py          (standard library only; oiiotool for the EXR seeds)

tests/fuzz/corpus_gltf/: small .gltf/.glb files covering what io::load_gltf reads (indexed and not,
strips, fans, sparse and quantised accessors, matrices, several primitives, a texture, a skin with a
clip, missing NORMAL / TEXCOORD_0) plus inputs it must reject. The Draco seed valid_draco.glb comes
from make_draco_seed.cpp. tests/fuzz/corpus_env_image/: tiny Radiance HDR (flat and run-length
encoded), PNG (8-bit RGB, 16-bit grey) and OpenEXR (several compressions, half, tiled; and the
fixture data/env.exr) images.
A seed named valid_* must load, invalid_* must be rejected (io_fuzz_corpus tests check both).
"""
import base64
import json
import os
import shutil
import struct
import subprocess
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
GLTF = os.path.join(HERE, "corpus_gltf")
IMG = os.path.join(HERE, "corpus_env_image")

FLOAT, USHORT, UBYTE, SHORT, BYTE = 5126, 5123, 5121, 5122, 5120


class Doc:
    """A glTF document with one binary buffer."""

    def __init__(self):
        self.doc = {"asset": {"version": "2.0"}, "buffers": [], "bufferViews": [], "accessors": []}
        self.bin = bytearray()

    def view(self, data):
        while len(self.bin) % 4:
            self.bin.append(0)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)})
        self.bin += data
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, fmt, values, ctype, type_, ncomp, normalized=False, minmax=False):
        v = self.view(struct.pack("<%d%s" % (len(values), fmt), *values))
        a = {"bufferView": v, "componentType": ctype, "count": len(values) // ncomp, "type": type_}
        if normalized:
            a["normalized"] = True
        if minmax:
            a["min"] = [min(values[k::ncomp]) for k in range(ncomp)]
            a["max"] = [max(values[k::ncomp]) for k in range(ncomp)]
        self.doc["accessors"].append(a)
        return len(self.doc["accessors"]) - 1

    def floats(self, values, type_, ncomp):
        return self.accessor("f", values, FLOAT, type_, ncomp, minmax=(type_ == "VEC3"))

    def ushorts(self, values, type_="SCALAR", ncomp=1):
        return self.accessor("H", values, USHORT, type_, ncomp)

    def glb(self):
        self.doc["buffers"] = [{"byteLength": len(self.bin)}] if self.bin else []
        js = json.dumps(self.doc, separators=(",", ":")).encode()
        js += b" " * (-len(js) % 4)
        body = bytearray(self.bin) + b"\0" * (-len(self.bin) % 4)
        out = struct.pack("<III", 0x46546C67, 2, 12 + 8 + len(js) + (8 + len(body) if body else 0))
        out += struct.pack("<II", len(js), 0x4E4F534A) + js
        if body:
            out += struct.pack("<II", len(body), 0x004E4942) + bytes(body)
        return out

    def gltf(self):
        uri = "data:application/octet-stream;base64," + base64.b64encode(bytes(self.bin)).decode()
        self.doc["buffers"] = [{"byteLength": len(self.bin), "uri": uri}]
        return json.dumps(self.doc, separators=(",", ":")).encode()


QUAD_POS = [-1, 0, -1, 1, 0, -1, 1, 0, 1, -1, 0, 1]
QUAD_NRM = [0, 1, 0] * 4
QUAD_UV = [0, 0, 1, 0, 1, 1, 0, 1]
QUAD_IDX = [0, 2, 1, 0, 3, 2]


def png(width, height, channels, bits, pixel):
    """A PNG of pixel(x, y) -> tuple of `channels` ints (colour type 0 grey, 2 RGB)."""
    rows = bytearray()
    for y in range(height):
        rows.append(0)
        for x in range(width):
            for v in pixel(x, y):
                rows += struct.pack(">H", v) if bits == 16 else bytes([v])
    ctype = {1: 0, 3: 2}[channels]

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, bits, ctype, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(bytes(rows))) + chunk(b"IEND", b""))


def quad(d, normals=True, uvs=False, indexed=True, material=None):
    # Not indexed: the 6 corners of the two triangles, in index order.
    take = (lambda v, n: v) if indexed else (lambda v, n: [v[n * i + k] for i in QUAD_IDX for k in range(n)])
    attrs = {"POSITION": d.floats(take(QUAD_POS, 3), "VEC3", 3)}
    if normals:
        attrs["NORMAL"] = d.floats(take(QUAD_NRM, 3), "VEC3", 3)
    if uvs:
        attrs["TEXCOORD_0"] = d.floats(take(QUAD_UV, 2), "VEC2", 2)
    prim = {"attributes": attrs}
    if indexed:
        prim["indices"] = d.ushorts(QUAD_IDX)
    if material is not None:
        prim["material"] = material
    return prim


def one_node(d, prims, node=None):
    d.doc["meshes"] = [{"name": "quad", "primitives": prims}]
    d.doc["nodes"] = [dict({"name": "quad_node", "mesh": 0}, **(node or {}))]
    d.doc["scenes"] = [{"nodes": [0]}]
    d.doc["scene"] = 0


def textured(d):
    tex = png(2, 2, 3, 8, lambda x, y: (255 * x, 255 * y, 128))
    d.doc["images"] = [{"bufferView": d.view(tex), "mimeType": "image/png"}]
    d.doc["textures"] = [{"source": 0}]
    d.doc["materials"] = [{"name": "paint", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.6, 0.7, 1],
                                                                      "baseColorTexture": {"index": 0}}}]


def gltf_seeds():
    out = {}
    d = Doc(); one_node(d, [quad(d)]); out["valid_quad.glb"] = d.glb()
    d = Doc(); one_node(d, [quad(d)], {"translation": [1, 2, 3]}); out["valid_quad.gltf"] = d.gltf()
    d = Doc(); one_node(d, [quad(d, normals=False)]); out["valid_no_normals.glb"] = d.glb()
    d = Doc(); one_node(d, [quad(d, indexed=False)]); out["valid_not_indexed.glb"] = d.glb()
    d = Doc(); textured(d); one_node(d, [quad(d, uvs=True, material=0)]); out["valid_textured.glb"] = d.glb()
    d = Doc(); textured(d); one_node(d, [quad(d, uvs=True, material=0), quad(d, normals=False, material=0)])
    out["valid_textured_no_uv.glb"] = d.glb()
    d = Doc(); p = quad(d); p["indices"] = d.ushorts([1, 0, 2, 3]); p["mode"] = 5; one_node(d, [p])
    out["valid_strip.glb"] = d.glb()
    d = Doc(); p = quad(d); p["indices"] = d.ushorts([0, 3, 2, 1]); p["mode"] = 6; one_node(d, [p])
    out["valid_fan.glb"] = d.glb()
    d = Doc(); p = quad(d)
    iv = d.view(struct.pack("<H", 2)); vv = d.view(struct.pack("<3f", 1, 0, 3))
    d.doc["accessors"][0]["sparse"] = {"count": 1, "indices": {"bufferView": iv, "componentType": USHORT},
                                       "values": {"bufferView": vv}}
    one_node(d, [p]); out["valid_sparse.glb"] = d.glb()
    d = Doc(); one_node(d, [quad(d)], {"matrix": [0, 0, -2, 0, 0, 2, 0, 0, 2, 0, 0, 0, 1, 2, 3, 1]})
    out["valid_matrix.glb"] = d.glb()
    # KHR_mesh_quantization: normalised shorts for positions, normalised bytes for normals.
    d = Doc()
    pos = d.accessor("h", [int(v * 32767) for v in QUAD_POS], SHORT, "VEC3", 3, normalized=True, minmax=True)
    nrm = d.accessor("b", [int(v * 127) for v in QUAD_NRM], BYTE, "VEC3", 3, normalized=True)
    one_node(d, [{"attributes": {"POSITION": pos, "NORMAL": nrm}, "indices": d.ushorts(QUAD_IDX)}])
    d.doc["extensionsUsed"] = d.doc["extensionsRequired"] = ["KHR_mesh_quantization"]
    out["valid_quantized.glb"] = d.glb()
    # Nodes out of depth-first order, a mesh shared by two nodes.
    d = Doc(); one_node(d, [quad(d)])
    d.doc["nodes"] = [{"name": "second", "mesh": 0, "translation": [3, 0, 0]}, {"name": "root", "children": [2, 0]},
                      {"name": "first", "mesh": 0, "rotation": [0, 0.7071068, 0, 0.7071068]}]
    d.doc["scenes"] = [{"nodes": [1]}]
    out["valid_hierarchy.glb"] = d.glb()
    # A two-bone skinned strip with LINEAR, STEP and CUBICSPLINE channels, no NORMAL.
    d = Doc()
    pos, wts, jnt = [], [], []
    for i in range(4):
        for x in (-0.5, 0.5):
            pos += [x, float(i), 0.0]
            w = i / 3.0
            jnt += [0, 1, 0, 0]
            wts += [1 - w, w, 0, 0]
    idx = []
    for i in range(3):
        a = 2 * i
        idx += [a, a + 1, a + 3, a, a + 3, a + 2]
    ibm = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -1.5, 0, 1]
    attrs = {"POSITION": d.floats(pos, "VEC3", 3), "JOINTS_0": d.ushorts(jnt, "VEC4", 4),
             "WEIGHTS_0": d.floats(wts, "VEC4", 4)}
    prim = {"attributes": attrs, "indices": d.ushorts(idx)}
    times = d.floats([0, 1, 2], "SCALAR", 1)
    rot = d.floats([0, 0, 0, 1, 0, 0, 0.247, 0.969, 0, 0, 0, 1], "VEC4", 4)
    tr = d.floats([0, 0, 0, 0, 0.25, 0, 0, 0, 0], "VEC3", 3)
    sc = d.floats([0, 0, 0, 1, 1, 1, 0, 0, 0] * 3, "VEC3", 3)
    d.doc["meshes"] = [{"name": "strip", "primitives": [prim]}]
    d.doc["nodes"] = [{"name": "strip", "mesh": 0, "skin": 0}, {"name": "root", "children": [2]},
                      {"name": "tip", "translation": [0, 1.5, 0]}]
    d.doc["skins"] = [{"joints": [1, 2], "inverseBindMatrices": d.floats(ibm, "MAT4", 16)}]
    d.doc["animations"] = [{"name": "wave", "channels": [
        {"sampler": 0, "target": {"node": 2, "path": "rotation"}},
        {"sampler": 1, "target": {"node": 1, "path": "translation"}},
        {"sampler": 2, "target": {"node": 1, "path": "scale"}}], "samplers": [
        {"input": times, "output": rot}, {"input": times, "output": tr, "interpolation": "STEP"},
        {"input": times, "output": sc, "interpolation": "CUBICSPLINE"}]}]
    d.doc["scenes"] = [{"nodes": [0, 1]}]
    out["valid_skinned.glb"] = d.glb()
    # Inputs to reject.
    d = Doc(); one_node(d, [quad(d)], {"scale": [1e30, 1e30, 1e30]}); out["invalid_scale.glb"] = d.glb()
    d = Doc(); p = quad(d); p["indices"] = d.ushorts([0, 2, 9]); one_node(d, [p]); out["invalid_index.glb"] = d.glb()
    d = Doc(); one_node(d, [quad(d)]); out["invalid_truncated.glb"] = d.glb()[:-40]
    d = Doc(); one_node(d, [quad(d)]); d.doc["asset"]["extras"] = "NEST"
    out["invalid_deep.gltf"] = d.gltf().replace(b'"NEST"', b"[" * 65 + b"]" * 65)
    return out


def rgbe(r, g, b):
    m = max(r, g, b)
    if m < 1e-32:
        return bytes(4)
    import math
    f, e = math.frexp(m)
    s = f * 256.0 / m
    return bytes([int(r * s), int(g * s), int(b * s), e + 128])


def hdr_flat(width, height, pixel):
    head = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\nEXPOSURE=1.0\n\n-Y %d +X %d\n" % (height, width)
    return head + b"".join(rgbe(*pixel(x, y)) for y in range(height) for x in range(width))


def hdr_rle(width, height, pixel):
    """New-style run-length encoding (scanlines of 8..32767 pixels): runs and literal dumps."""
    out = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (height, width))
    for y in range(height):
        px = [rgbe(*pixel(x, y)) for x in range(width)]
        out += bytes([2, 2, width >> 8, width & 255])
        for c in range(4):
            chan = [p[c] for p in px]
            i = 0
            while i < width:
                run = 1
                while i + run < width and chan[i + run] == chan[i] and run < 127:
                    run += 1
                if run >= 3:
                    out += bytes([128 + run, chan[i]])
                    i += run
                else:
                    n = min(128, width - i)
                    out += bytes([n]) + bytes(chan[i:i + n])
                    i += n
    return bytes(out)


def image_seeds():
    out = {}
    sky = lambda x, y: (0.2 + 0.1 * x, 0.5 + 0.05 * y, 1.5 + y)
    out["valid_flat.hdr"] = hdr_flat(4, 2, sky)
    out["valid_rle.hdr"] = hdr_rle(16, 4, lambda x, y: (1.0, 0.5, 0.25) if x < 10 else sky(x, y))
    out["valid_rgb8.png"] = png(4, 2, 3, 8, lambda x, y: (60 * x, 120 * y, 200))
    out["valid_grey16.png"] = png(3, 3, 1, 16, lambda x, y: (7000 * (x + 3 * y),))
    out["invalid_truncated.hdr"] = hdr_rle(16, 4, sky)[:-20]
    out["invalid_empty.hdr"] = b"#?RADIANCE\n\n"
    return out


def exr_seeds():
    """OpenEXR through oiiotool: several compressions, half and float, scanline and tiled."""
    if not shutil.which("oiiotool"):
        print("make_seeds: oiiotool not found (Debian package openimageio-tools); EXR seeds skipped")
        return
    variants = {"valid_zip_float.exr": ["-d", "float", "--compression", "zip"],
                "valid_piz_half.exr": ["-d", "half", "--compression", "piz"],
                "valid_rle_half.exr": ["-d", "half", "--compression", "rle"],
                "valid_pxr24_float.exr": ["-d", "float", "--compression", "pxr24"],
                "valid_b44_half.exr": ["-d", "half", "--compression", "b44"],
                "valid_tiled_half.exr": ["-d", "half", "--tile", "4", "4", "--compression", "zips"]}
    for name, args in variants.items():
        subprocess.run(["oiiotool", "--pattern", "fill:top=0.1,0.2,0.3:bottom=4,2,1", "8x4", "3"] + args +
                       ["-o", os.path.join(IMG, name)], check=True)


def main():
    os.makedirs(GLTF, exist_ok=True)
    os.makedirs(IMG, exist_ok=True)
    for folder, seeds in ((GLTF, gltf_seeds()), (IMG, image_seeds())):
        for name, data in seeds.items():
            with open(os.path.join(folder, name), "wb") as f:
                f.write(data)
    shutil.copyfile(os.path.join(HERE, "data", "env.exr"), os.path.join(IMG, "valid_env.exr"))
    exr_seeds()
    print("make_seeds: %d glTF seeds, %d image seeds" % (len(os.listdir(GLTF)), len(os.listdir(IMG))))


if __name__ == "__main__":
    main()
