// glTF / GLB loading: files written by the tests themselves (test_support.hpp) with known contents,
// a Draco-compressed file produced with draco::Encoder, and the real bunny when the asset set is there.
#include <draco/compression/encode.h>
#include <draco/core/encoder_buffer.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/image.hpp"
#include "softgi/io/gltf.hpp"
#include "softgi/io/image_io.hpp"
#include "softgi/io/scene_file.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/scene/scene.hpp"
#include "test_support.hpp"

namespace {

using softgi::io::GltfImport;
using softgi::io::load_gltf;
using softgi::scene::Scene;
using softgi::test::GltfBuilder;
using softgi::test::ScratchDir;

// Float data written and read back through the file must come back bit-exact.
constexpr float kExact = 0.0f;
// Quaternions rebuilt from a rotation matrix: a few float ulps of the matrix entries.
constexpr float kDecomposeTolerance = 1e-5f;

template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no exception)";
}

// Unit quad in the xz plane facing +y, as 4 indexed vertices.
const std::vector<float> kQuadPos = {-1, 0, -1, 1, 0, -1, 1, 0, 1, -1, 0, 1};
const std::vector<float> kQuadNrm = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
const std::vector<std::uint16_t> kQuadIdx = {0, 2, 1, 0, 3, 2};

void add_quad_mesh(GltfBuilder& b, bool with_normals, bool indexed = true) {
  nlohmann::json attrs;
  if (indexed) {
    attrs["POSITION"] = b.floats(kQuadPos, "VEC3", 3);
    if (with_normals) attrs["NORMAL"] = b.floats(kQuadNrm, "VEC3", 3);
  } else {
    std::vector<float> p, n;
    for (std::uint16_t i : kQuadIdx) {
      for (int k = 0; k < 3; ++k) {
        p.push_back(kQuadPos[3 * i + k]);
        n.push_back(kQuadNrm[3 * i + k]);
      }
    }
    attrs["POSITION"] = b.floats(p, "VEC3", 3);
    if (with_normals) attrs["NORMAL"] = b.floats(n, "VEC3", 3);
  }
  nlohmann::json prim = {{"attributes", attrs}, {"material", 0}};
  if (indexed) prim["indices"] = b.ushorts(kQuadIdx, "SCALAR", 1);
  b.doc["meshes"] = {{{"name", "quad"}, {"primitives", {prim}}}};
  b.doc["materials"] = {{{"name", "paint"}, {"pbrMetallicRoughness", {{"baseColorFactor", {0.25, 0.5, 0.75, 1.0}}}}}};
  b.doc["nodes"] = {{{"name", "quad_node"}, {"mesh", 0}, {"translation", {1.0, 2.0, 3.0}}}};
  b.doc["scenes"] = {{{"nodes", {0}}}};
  b.doc["scene"] = 0;
}

TEST(io_gltf, TwoTriangleQuadLoadsExactly) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, true);
  b.write_glb(dir.file("quad.glb"));
  Scene s;
  const GltfImport imp = load_gltf(dir.file("quad.glb"), s);
  ASSERT_EQ(imp.meshes_added, 1);
  ASSERT_EQ(s.meshes.size(), 1u);
  const auto& m = s.meshes[0];
  EXPECT_EQ(m.name, "quad");
  ASSERT_EQ(m.positions.size(), 4u);
  ASSERT_EQ(m.triangles.size(), 2u);
  for (int i = 0; i < 4; ++i) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(m.positions[i][k], kQuadPos[3 * i + k], kExact);
      EXPECT_NEAR(m.normals[i][k], kQuadNrm[3 * i + k], kExact);
    }
  }
  EXPECT_EQ(m.triangles[0], glm::uvec3(0, 2, 1));
  EXPECT_EQ(m.triangles[1], glm::uvec3(0, 3, 2));
  ASSERT_EQ(s.materials.size(), 1u);
  EXPECT_EQ(m.material, 0);
  EXPECT_EQ(s.materials[0].name, "paint");
  EXPECT_EQ(s.materials[0].albedo, glm::vec3(0.25f, 0.5f, 0.75f));
  ASSERT_EQ(s.nodes.size(), 1u);
  EXPECT_EQ(s.nodes[0].mesh, 0);
  EXPECT_EQ(s.nodes[0].translation, glm::vec3(1, 2, 3));
  ASSERT_EQ(imp.root_nodes, std::vector<int>{0});
  EXPECT_NO_THROW(softgi::scene::validate(s));
}

TEST(io_gltf, NonIndexedAndSeparateBinFile) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, true, false);
  b.write_gltf(dir.file("quad.gltf"), "quad_data.bin");
  Scene s;
  load_gltf(dir.file("quad.gltf"), s);
  ASSERT_EQ(s.meshes.size(), 1u);
  EXPECT_EQ(s.meshes[0].positions.size(), 6u);
  ASSERT_EQ(s.meshes[0].triangles.size(), 2u);
  EXPECT_EQ(s.meshes[0].triangles[1], glm::uvec3(3, 4, 5));
}

TEST(io_gltf, AppendsWithOffsetIndices) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, true);
  b.write_glb(dir.file("quad.glb"));
  Scene s;
  load_gltf(dir.file("quad.glb"), s);
  const GltfImport second = load_gltf(dir.file("quad.glb"), s);
  ASSERT_EQ(s.meshes.size(), 2u);
  ASSERT_EQ(s.materials.size(), 2u);
  ASSERT_EQ(s.nodes.size(), 2u);
  EXPECT_EQ(second.root_nodes, std::vector<int>{1});
  EXPECT_EQ(s.nodes[1].mesh, 1);
  EXPECT_EQ(s.meshes[1].material, 1);
  EXPECT_NO_THROW(softgi::scene::validate(s));
}

TEST(io_gltf, NodeMatrixIsDecomposedIntoTrs) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, true);
  const glm::vec3 t(0.5f, -2.0f, 3.0f), sc(2.0f, 0.5f, 1.5f);
  const glm::quat r = glm::normalize(glm::angleAxis(0.7f, glm::normalize(glm::vec3(1, 2, 3))));
  const glm::mat4 m = glm::translate(glm::mat4(1.0f), t) * glm::mat4_cast(r) * glm::scale(glm::mat4(1.0f), sc);
  std::vector<double> mv(glm::value_ptr(m), glm::value_ptr(m) + 16);
  b.doc["nodes"][0].erase("translation");
  b.doc["nodes"][0]["matrix"] = mv;
  b.write_glb(dir.file("m.glb"));
  Scene s;
  load_gltf(dir.file("m.glb"), s);
  const auto& n = s.nodes[0];
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(n.translation[k], t[k], kDecomposeTolerance);
    EXPECT_NEAR(n.scale[k], sc[k], kDecomposeTolerance);
  }
  // q and -q are the same rotation.
  EXPECT_NEAR(std::fabs(glm::dot(n.rotation, r)), 1.0f, kDecomposeTolerance);
}

TEST(io_gltf, ShearedMatrixIsAnError) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, true);
  b.doc["nodes"][0].erase("translation");
  b.doc["nodes"][0]["matrix"] = {1, 0, 0, 0, 0.5, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  b.write_glb(dir.file("shear.glb"));
  Scene s;
  const std::string e = error_of([&] { load_gltf(dir.file("shear.glb"), s); });
  EXPECT_NE(e.find("shear.glb"), std::string::npos) << e;
  EXPECT_NE(e.find("node 0 'quad_node'"), std::string::npos) << e;
  EXPECT_NE(e.find("shear"), std::string::npos) << e;
  EXPECT_TRUE(s.meshes.empty() && s.nodes.empty()) << "a failed load must leave the scene unchanged";
}

// ---- flat normals (glTF 2.0 section 3.7.2.1: a primitive without NORMAL is flat shaded) ----

// A tetrahedron with 4 shared vertices, each face counter-clockwise seen from outside, plus two
// degenerate triangles (a repeated index; a collinear one through the midpoint vertex 4), with a
// TEXCOORD_0 and COLOR_0 that tell the original vertices apart.
const std::vector<float> kTetPos = {0.1f, -0.2f, 0.3f, 1.7f, 0.1f, -0.4f, 0.3f, 1.3f, 0.2f, 0.6f, 0.4f, 1.9f,
                                    0.9f, -0.05f, -0.05f};
const std::vector<std::uint16_t> kTetIdx = {0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2, 0, 1, 1, 0, 4, 1};
constexpr int kTetFaces = 4;

void add_tet_mesh(GltfBuilder& b, bool reverse_winding) {
  std::vector<float> uv, col;
  for (int i = 0; i < 5; ++i) {
    uv.insert(uv.end(), {0.1f * float(i), 0.05f * float(i * i)});
    col.insert(col.end(), {0.2f * float(i), 1.0f - 0.2f * float(i), 0.5f});
  }
  std::vector<std::uint16_t> idx = kTetIdx;
  if (reverse_winding) {
    for (std::size_t t = 0; t < idx.size(); t += 3) std::swap(idx[t + 1], idx[t + 2]);
  }
  nlohmann::json attrs = {{"POSITION", b.floats(kTetPos, "VEC3", 3)},
                          {"TEXCOORD_0", b.floats(uv, "VEC2", 2)},
                          {"COLOR_0", b.floats(col, "VEC3", 3)}};
  b.doc["meshes"] = {{{"name", "tet"}, {"primitives", {{{"attributes", attrs}, {"indices", b.ushorts(idx, "SCALAR", 1)}}}}}};
  b.doc["nodes"] = {{{"name", "tet_node"}, {"mesh", 0}}};
  b.doc["scenes"] = {{{"nodes", {0}}}};
  b.doc["scene"] = 0;
}

glm::dvec3 tet_vertex(int i) { return glm::dvec3(kTetPos[3 * i], kTetPos[3 * i + 1], kTetPos[3 * i + 2]); }

// The flat normals are the face normals normalize((p1 - p0) x (p2 - p0)) (counter-clockwise is the
// front face, glTF 2.0 section 3.7.2.1), each triangle has its own 3 vertices and they keep the
// uv and colour of the shared vertex they came from.
TEST(io_gltf, MissingNormalsGetFlatNormalsOnSplitVertices) {
  // Normals are computed in double and rounded to float once: a few float ulps.
  constexpr float kFlatNormalTolerance = 1e-6f;
  for (const bool reversed : {false, true}) {
    ScratchDir dir;
    GltfBuilder b;
    add_tet_mesh(b, reversed);
    b.write_glb(dir.file("tet.glb"));
    Scene s;
    load_gltf(dir.file("tet.glb"), s);
    ASSERT_EQ(s.meshes.size(), 1u);
    const auto& m = s.meshes[0];
    ASSERT_EQ(m.triangles.size(), std::size_t(kTetFaces)) << "the two degenerate triangles are dropped";
    ASSERT_EQ(m.positions.size(), 3 * m.triangles.size());
    ASSERT_EQ(m.normals.size(), m.positions.size());
    ASSERT_EQ(m.uvs.size(), m.positions.size());
    ASSERT_EQ(m.colors.size(), m.positions.size());
    const glm::dvec3 centroid = 0.25 * (tet_vertex(0) + tet_vertex(1) + tet_vertex(2) + tet_vertex(3));
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
      const auto f = std::uint32_t(3 * t);
      EXPECT_EQ(m.triangles[t], glm::uvec3(f, f + 1, f + 2));
      // The original triangle, in the file's order.
      int orig[3];
      for (int k = 0; k < 3; ++k) {
        std::uint16_t i = kTetIdx[3 * t + std::size_t(k)];
        if (reversed && k > 0) i = kTetIdx[3 * t + std::size_t(3 - k)];
        orig[k] = i;
        EXPECT_EQ(m.positions[f + std::uint32_t(k)], glm::vec3(tet_vertex(i))) << "triangle " << t << " corner " << k;
        EXPECT_EQ(m.uvs[f + std::uint32_t(k)], glm::vec2(0.1f * float(i), 0.05f * float(i * i)));
        EXPECT_EQ(m.colors[f + std::uint32_t(k)], glm::vec3(0.2f * float(i), 1.0f - 0.2f * float(i), 0.5f));
      }
      const glm::dvec3 p0 = tet_vertex(orig[0]), p1 = tet_vertex(orig[1]), p2 = tet_vertex(orig[2]);
      const glm::dvec3 expect = glm::normalize(glm::cross(p1 - p0, p2 - p0));
      const glm::dvec3 outward = (p0 + p1 + p2) / 3.0 - centroid;
      for (int k = 0; k < 3; ++k) {
        const glm::vec3 nk = m.normals[f + std::uint32_t(k)];
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(nk[c], expect[c], kFlatNormalTolerance) << "triangle " << t;
        // The faces are wound counter-clockwise seen from outside: the normals point out, or in
        // when the file's winding is reversed.
        EXPECT_EQ(glm::dot(glm::dvec3(nk), outward) > 0.0, !reversed) << "triangle " << t;
      }
    }
    ASSERT_EQ(s.notices.size(), 1u);
    EXPECT_NE(s.notices[0].find("tet.glb: mesh 0 'tet' primitive 0 has no NORMAL: flat normals"), std::string::npos)
        << s.notices[0];
    EXPECT_NE(s.notices[0].find("5 vertices split into 12"), std::string::npos) << s.notices[0];
    EXPECT_NO_THROW(softgi::scene::validate(s));
  }
}

TEST(io_gltf, MissingNormalsOnAllDegenerateTrianglesIsAnError) {
  ScratchDir dir;
  GltfBuilder b;
  add_tet_mesh(b, false);
  b.doc["meshes"][0]["primitives"][0]["indices"] = b.ushorts({0, 1, 1, 0, 4, 1}, "SCALAR", 1);
  b.write_glb(dir.file("sliver.glb"));
  Scene s;
  const std::string e = error_of([&] { load_gltf(dir.file("sliver.glb"), s); });
  EXPECT_NE(e.find("sliver.glb: mesh 0 'tet' primitive 0: no non-degenerate triangles"), std::string::npos) << e;
  EXPECT_TRUE(s.meshes.empty() && s.notices.empty()) << "a failed load must leave the scene unchanged";
}

// The quad with normals given and without: the flat normals equal the given ones (+y, from the
// counter-clockwise winding) and the split vertices repeat the welded ones triangle by triangle.
TEST(io_gltf, FlatNormalsOfTheQuadMatchItsGivenNormals) {
  ScratchDir dir;
  GltfBuilder with, without;
  add_quad_mesh(with, true);
  add_quad_mesh(without, false);
  with.write_glb(dir.file("with.glb"));
  without.write_glb(dir.file("nonormals.glb"));
  Scene a, b;
  load_gltf(dir.file("with.glb"), a);
  load_gltf(dir.file("nonormals.glb"), b);
  const auto &ma = a.meshes[0], &mb = b.meshes[0];
  ASSERT_EQ(ma.positions.size(), 4u);
  ASSERT_EQ(mb.positions.size(), 6u);
  ASSERT_EQ(mb.triangles.size(), ma.triangles.size());
  for (std::size_t t = 0; t < ma.triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(mb.positions[mb.triangles[t][k]], ma.positions[ma.triangles[t][k]]);
      EXPECT_EQ(mb.normals[mb.triangles[t][k]], ma.normals[ma.triangles[t][k]]);
    }
  }
  EXPECT_TRUE(a.notices.empty());
  ASSERT_EQ(b.notices.size(), 1u);
  EXPECT_NE(b.notices[0].find("nonormals.glb: mesh 0 'quad' primitive 0 has no NORMAL"), std::string::npos) << b.notices[0];
}


TEST(io_gltf, TruncatedGlbIsAnError) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, true);
  std::vector<unsigned char> bytes = b.glb();
  bytes.resize(bytes.size() - 40);
  softgi::test::write_bytes(dir.file("cut.glb"), bytes);
  Scene s;
  const std::string e = error_of([&] { load_gltf(dir.file("cut.glb"), s); });
  EXPECT_NE(e.find("cut.glb"), std::string::npos) << e;
  EXPECT_NE(e.find("truncated GLB"), std::string::npos) << e;
  // A header cut short as well.
  bytes.resize(10);
  softgi::test::write_bytes(dir.file("cut.glb"), bytes);
  EXPECT_NE(error_of([&] { load_gltf(dir.file("cut.glb"), s); }).find("truncated GLB"), std::string::npos);
}

// A BIN chunk that declares more bytes than follow its header, with the file's total length
// consistent with the cut: the payload must not be read from beyond the file.
TEST(io_gltf, BinChunkLongerThanTheFileIsAnError) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, true);
  std::vector<unsigned char> bytes = b.glb();
  const auto u32_at = [&](std::size_t at) {
    return std::uint32_t(bytes[at]) | std::uint32_t(bytes[at + 1]) << 8 | std::uint32_t(bytes[at + 2]) << 16 |
           std::uint32_t(bytes[at + 3]) << 24;
  };
  const std::size_t bin_header = 20 + u32_at(12);
  ASSERT_LT(bin_header + 8, bytes.size()) << "the builder's GLB has a BIN chunk";
  ASSERT_EQ(bin_header + 8 + u32_at(bin_header), bytes.size());
  // Less than the 8 bytes tinygltf's own bound leaves out.
  const std::uint32_t cut = 4;
  bytes.resize(bytes.size() - cut);
  const std::uint32_t length = u32_at(8) - cut;
  for (int i = 0; i < 4; ++i) bytes[8 + i] = static_cast<unsigned char>(length >> (8 * i));
  softgi::test::write_bytes(dir.file("longbin.glb"), bytes);
  Scene s;
  const std::string e = error_of([&] { load_gltf(dir.file("longbin.glb"), s); });
  EXPECT_NE(e.find("longbin.glb: truncated GLB: the BIN chunk declares"), std::string::npos) << e;
  // A tail too short for a chunk header.
  bytes.resize(bin_header + 4);
  for (int i = 0; i < 4; ++i) bytes[8 + i] = static_cast<unsigned char>((bin_header + 4) >> (8 * i));
  softgi::test::write_bytes(dir.file("longbin.glb"), bytes);
  EXPECT_NE(error_of([&] { load_gltf(dir.file("longbin.glb"), s); }).find("too few for a chunk header"),
            std::string::npos);
}

TEST(io_gltf, MissingAndMalformedFilesAreErrors) {
  ScratchDir dir;
  Scene s;
  std::string e = error_of([&] { load_gltf(dir.file("absent.glb"), s); });
  EXPECT_NE(e.find("absent.glb: no such file"), std::string::npos) << e;
  softgi::test::write_text(dir.file("broken.gltf"), "{\"asset\": {\"version\": \"2.0\"}, \"meshes\": [");
  e = error_of([&] { load_gltf(dir.file("broken.gltf"), s); });
  EXPECT_NE(e.find("broken.gltf: cannot parse glTF"), std::string::npos) << e;
}

TEST(io_gltf, IndexBeyondVertexCountIsAnError) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, true);
  // Replace the index accessor with one that points past the 4 vertices.
  b.doc["meshes"][0]["primitives"][0]["indices"] = b.ushorts({0, 2, 9}, "SCALAR", 1);
  b.write_glb(dir.file("badindex.glb"));
  Scene s;
  const std::string e = error_of([&] { load_gltf(dir.file("badindex.glb"), s); });
  EXPECT_NE(e.find("badindex.glb: mesh 0 'quad' primitive 0: index 2 is 9, beyond the 4 vertices"), std::string::npos) << e;
}

TEST(io_gltf, AccessorPastItsBufferIsAnError) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, true);
  b.doc["accessors"][0]["count"] = 400;  // POSITION claims 400 vertices in a 48-byte view
  b.write_glb(dir.file("overrun.glb"));
  Scene s;
  const std::string e = error_of([&] { load_gltf(dir.file("overrun.glb"), s); });
  EXPECT_NE(e.find("overrun.glb"), std::string::npos) << e;
  EXPECT_NE(e.find("POSITION"), std::string::npos) << e;
}

TEST(io_gltf, SparseAccessorOverridesValues) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, true);
  const std::vector<std::uint16_t> which = {2};
  const std::vector<float> value = {1.0f, 0.0f, 3.0f};
  const int iv = b.view(which.data(), 2), vv = b.view(value.data(), 12);
  b.doc["accessors"][0]["sparse"] = {{"count", 1},
                                     {"indices", {{"bufferView", iv}, {"componentType", 5123}}},
                                     {"values", {{"bufferView", vv}}}};
  b.write_glb(dir.file("sparse.glb"));
  Scene s;
  load_gltf(dir.file("sparse.glb"), s);
  EXPECT_EQ(s.meshes[0].positions[2], glm::vec3(1, 0, 3));
  EXPECT_EQ(s.meshes[0].positions[1], glm::vec3(1, 0, -1));
}

TEST(io_gltf, TriangleStripIsTriangulatedWithAlternatingWinding) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, true);
  // Strip 0 1 3 2 covers the quad with two triangles, both facing +y after unwinding.
  b.doc["meshes"][0]["primitives"][0]["indices"] = b.ushorts({1, 0, 2, 3}, "SCALAR", 1);
  b.doc["meshes"][0]["primitives"][0]["mode"] = 5;
  b.write_glb(dir.file("strip.glb"));
  Scene s;
  load_gltf(dir.file("strip.glb"), s);
  const auto& m = s.meshes[0];
  ASSERT_EQ(m.triangles.size(), 2u);
  for (const auto& t : m.triangles) {
    const glm::vec3 n = glm::cross(m.positions[t[1]] - m.positions[t[0]], m.positions[t[2]] - m.positions[t[0]]);
    EXPECT_GT(n.y, 0.0f) << "triangle " << t[0] << " " << t[1] << " " << t[2] << " faces away from its normals";
  }
}

TEST(io_gltf, BaseColorTextureIsDecodedToLinear) {
  ScratchDir dir;
  // A 2x1 PNG: byte values 0..255 known exactly, so the sRGB decode can be checked.
  softgi::Image img(2, 1);
  img.at(0, 0) = glm::vec3(0.0f, 128.0f / 255.0f, 1.0f);
  img.at(1, 0) = glm::vec3(64.0f / 255.0f, 200.0f / 255.0f, 32.0f / 255.0f);
  softgi::io::write_png_display(dir.file("tex.png"), img);
  const std::vector<unsigned char> png = softgi::test::read_bytes(dir.file("tex.png"));
  GltfBuilder b;
  add_quad_mesh(b, true);
  const int pv = b.view(png.data(), png.size());
  b.doc["images"] = {{{"bufferView", pv}, {"mimeType", "image/png"}, {"name", "tex"}}};
  b.doc["textures"] = {{{"source", 0}}};
  b.doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 0}};
  b.write_glb(dir.file("textured.glb"));
  Scene s;
  load_gltf(dir.file("textured.glb"), s);
  ASSERT_EQ(s.textures.size(), 1u);
  EXPECT_EQ(s.materials[0].albedo_texture, 0);
  const auto& t = s.textures[0];
  ASSERT_EQ(t.width, 2);
  ASSERT_EQ(t.height, 1);
  auto lin = [](float v) { return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f); };
  // One float rounding step of the decode.
  constexpr float kDecodeTolerance = 1e-6f;
  for (int x = 0; x < 2; ++x) {
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(t.texels[std::size_t(x)][k], lin(img.at(x, 0)[k]), kDecodeTolerance);
  }
}

// A two-bone strip: joint 0 at the origin, joint 1 (child) at y = 1.5, animated with LINEAR rotation
// keys, STEP translation keys and CUBICSPLINE scale keys.
void write_skinned(GltfBuilder& b) {
  std::vector<float> pos, nrm, wts;
  std::vector<std::uint16_t> jnt;
  for (int i = 0; i < 4; ++i) {
    for (float x : {-0.5f, 0.5f}) {
      pos.insert(pos.end(), {x, float(i), 0.0f});
      nrm.insert(nrm.end(), {0.0f, 0.0f, 1.0f});
      const float w = float(i) / 3.0f;
      jnt.insert(jnt.end(), {0, 1, 0, 0});
      wts.insert(wts.end(), {1.0f - w, w, 0.0f, 0.0f});
    }
  }
  std::vector<std::uint16_t> idx;
  for (std::uint16_t i = 0; i < 3; ++i) {
    const std::uint16_t a = std::uint16_t(2 * i);
    idx.insert(idx.end(), {a, std::uint16_t(a + 1), std::uint16_t(a + 3), a, std::uint16_t(a + 3), std::uint16_t(a + 2)});
  }
  const std::vector<float> ibm = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1,
                                  1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -1.5f, 0, 1};
  const float s = std::sin(0.25f), c = std::cos(0.25f);
  nlohmann::json attrs = {{"POSITION", b.floats(pos, "VEC3", 3)},
                          {"NORMAL", b.floats(nrm, "VEC3", 3)},
                          {"JOINTS_0", b.ushorts(jnt, "VEC4", 4)},
                          {"WEIGHTS_0", b.floats(wts, "VEC4", 4)}};
  const int ind = b.ushorts(idx, "SCALAR", 1);
  const int ibm_acc = b.floats(ibm, "MAT4", 16);
  const int times = b.floats({0.0f, 1.0f, 2.0f}, "SCALAR", 1);
  const int rot = b.floats({0, 0, 0, 1, 0, 0, s, c, 0, 0, 0, 1}, "VEC4", 4);
  const int tr = b.floats({0, 0, 0, 0, 0.25f, 0, 0, 0, 0}, "VEC3", 3);
  // CUBICSPLINE: (in-tangent, value, out-tangent) per key; tangents are deliberately absurd so that
  // using them instead of the values would show.
  const int sc = b.floats({9, 9, 9, 1, 1, 1, 9, 9, 9,  //
                           9, 9, 9, 2, 2, 2, 9, 9, 9,  //
                           9, 9, 9, 1, 1, 1, 9, 9, 9},
                          "VEC3", 3);
  b.doc["meshes"] = {{{"name", "strip"}, {"primitives", {{{"attributes", attrs}, {"indices", ind}}}}}};
  b.doc["nodes"] = {{{"name", "strip"}, {"mesh", 0}, {"skin", 0}},
                    {{"name", "root"}, {"children", {2}}},
                    {{"name", "tip"}, {"translation", {0.0, 1.5, 0.0}}}};
  b.doc["skins"] = {{{"name", "rig"}, {"joints", {1, 2}}, {"inverseBindMatrices", ibm_acc}}};
  b.doc["animations"] = {{{"name", "wave"},
                          {"channels",
                           {{{"sampler", 0}, {"target", {{"node", 2}, {"path", "rotation"}}}},
                            {{"sampler", 1}, {"target", {{"node", 1}, {"path", "translation"}}}},
                            {{"sampler", 2}, {"target", {{"node", 1}, {"path", "scale"}}}}}},
                          {"samplers",
                           {{{"input", times}, {"output", rot}, {"interpolation", "LINEAR"}},
                            {{"input", times}, {"output", tr}, {"interpolation", "STEP"}},
                            {{"input", times}, {"output", sc}, {"interpolation", "CUBICSPLINE"}}}}}};
  b.doc["scenes"] = {{{"nodes", {0, 1}}}};
  b.doc["scene"] = 0;
}

TEST(io_gltf, SkinAndAnimationAreImported) {
  ScratchDir dir;
  GltfBuilder b;
  write_skinned(b);
  b.write_glb(dir.file("skinned.glb"));
  Scene s;
  s.nodes.resize(2);  // pre-existing nodes: every index must be offset by 2
  const GltfImport imp = load_gltf(dir.file("skinned.glb"), s);
  ASSERT_EQ(s.nodes.size(), 5u);
  // Depth-first: strip (2), root (3), tip (4, child of root).
  EXPECT_EQ(imp.root_nodes, (std::vector<int>{2, 3}));
  EXPECT_EQ(s.nodes[4].name, "tip");
  EXPECT_EQ(s.nodes[4].parent, 3);
  EXPECT_EQ(s.nodes[2].skin, 0);
  ASSERT_EQ(s.skins.size(), 1u);
  EXPECT_EQ(s.skins[0].joints, (std::vector<int>{3, 4}));
  EXPECT_EQ(s.skins[0].inverse_bind[1][3], glm::vec4(0, -1.5f, 0, 1));
  const auto& m = s.meshes[0];
  ASSERT_TRUE(m.skinned());
  EXPECT_EQ(m.joints[7], glm::u16vec4(0, 1, 0, 0));
  EXPECT_EQ(m.weights[7], glm::vec4(0, 1, 0, 0));

  ASSERT_EQ(imp.clips, std::vector<int>{0});
  const auto& clip = s.clips[0];
  EXPECT_EQ(clip.name, "wave");
  EXPECT_EQ(clip.duration, 2.0f);
  ASSERT_EQ(clip.channels.size(), 3u);
  using Ch = softgi::scene::AnimationChannel;
  EXPECT_EQ(clip.channels[0].node, 4);
  EXPECT_EQ(clip.channels[0].path, Ch::Path::Rotation);
  EXPECT_EQ(clip.channels[0].interp, Ch::Interp::Linear);
  EXPECT_NEAR(clip.channels[0].values[1].z, std::sin(0.25f), kExact);
  EXPECT_EQ(clip.channels[1].interp, Ch::Interp::Step);
  EXPECT_EQ(clip.channels[1].values[1], glm::vec4(0, 0.25f, 0, 0));
  // CUBICSPLINE keeps the value keys (the middle of each triple), interpolated linearly.
  EXPECT_EQ(clip.channels[2].path, Ch::Path::Scale);
  EXPECT_EQ(clip.channels[2].interp, Ch::Interp::Linear);
  ASSERT_EQ(clip.channels[2].values.size(), 3u);
  EXPECT_EQ(clip.channels[2].values[1], glm::vec4(2, 2, 2, 0));
  EXPECT_EQ(clip.channels[2].times, (std::vector<float>{0, 1, 2}));
}

TEST(io_gltf, JointOutsideSkinIsAnError) {
  ScratchDir dir;
  GltfBuilder b;
  write_skinned(b);
  b.doc["skins"][0]["joints"] = {1};  // the mesh uses joint 1 too
  b.doc["skins"][0].erase("inverseBindMatrices");
  b.write_glb(dir.file("joints.glb"));
  Scene s;
  const std::string e = error_of([&] { load_gltf(dir.file("joints.glb"), s); });
  EXPECT_NE(e.find("joints.glb: mesh 0 'strip' primitive 0: vertex"), std::string::npos) << e;
  EXPECT_NE(e.find("uses joint 1 of a skin with 1"), std::string::npos) << e;
}

// The skinned strip without NORMAL: split into 3 vertices per triangle, each keeping the joints and
// weights of its shared vertex, so the posed (skinned) positions and normals equal those of the
// file with normals (whose normals, +z, are the strip's flat normals) corner by corner.
TEST(io_gltf, SkinnedFileWithoutNormalsStillPoses) {
  ScratchDir dir;
  GltfBuilder with, without;
  write_skinned(with);
  write_skinned(without);
  without.doc["meshes"][0]["primitives"][0]["attributes"].erase("NORMAL");
  with.write_glb(dir.file("skinned.glb"));
  without.write_glb(dir.file("skinned_flat.glb"));
  Scene a, b;
  load_gltf(dir.file("skinned.glb"), a);
  load_gltf(dir.file("skinned_flat.glb"), b);
  a.active_clip = 0;
  b.active_clip = 0;
  ASSERT_NO_THROW(softgi::scene::validate(b));
  const auto &ma = a.meshes[0], &mb = b.meshes[0];
  ASSERT_TRUE(mb.skinned());
  ASSERT_EQ(mb.positions.size(), 3 * mb.triangles.size());
  ASSERT_EQ(mb.triangles.size(), ma.triangles.size());
  for (const double t : {0.0, 0.5, 1.0, 1.75}) {
    const auto pa = softgi::scene::evaluate(a, t), pb = softgi::scene::evaluate(b, t);
    ASSERT_EQ(pa.objects.size(), 1u);
    ASSERT_EQ(pb.objects.size(), 1u);
    const auto &oa = pa.objects[0], &ob = pb.objects[0];
    for (std::size_t tri = 0; tri < ma.triangles.size(); ++tri) {
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t va = ma.triangles[tri][k], vb = mb.triangles[tri][k];
        EXPECT_EQ(mb.joints[vb], ma.joints[va]);
        EXPECT_EQ(mb.weights[vb], ma.weights[va]);
        // The same float operations on the same inputs: bit-exact.
        EXPECT_EQ(ob.positions[vb], oa.positions[va]) << "t = " << t << ", triangle " << tri << " corner " << k;
        EXPECT_EQ(ob.normals[vb], oa.normals[va]) << "t = " << t << ", triangle " << tri << " corner " << k;
      }
    }
  }
  // The pose moves the tip: the comparison above is not of two rest poses.
  const auto rest = softgi::scene::evaluate(b, 0.0), bent = softgi::scene::evaluate(b, 1.0);
  EXPECT_GT(glm::length(bent.objects[0].positions.back() - rest.objects[0].positions.back()), 0.1f);
}

// ---- base colour texture without TEXCOORD_0 ----

// Two primitives share a textured material; the second has no TEXCOORD_0. Rule: that primitive
// gets a copy of the material without the texture (named "NAME (untextured)"), so it shows the
// base colour factor, and a notice names the file, mesh and primitive.
TEST(io_gltf, TexturedMaterialWithoutTexcoordUsesTheBaseColourFactor) {
  ScratchDir dir;
  softgi::Image img(1, 1);
  img.at(0, 0) = glm::vec3(1.0f, 0.0f, 0.0f);
  softgi::io::write_png_display(dir.file("red.png"), img);
  const std::vector<unsigned char> png = softgi::test::read_bytes(dir.file("red.png"));
  GltfBuilder b;
  add_quad_mesh(b, true);
  nlohmann::json textured = b.doc["meshes"][0]["primitives"][0];
  textured["attributes"]["TEXCOORD_0"] = b.floats({0, 0, 1, 0, 1, 1, 0, 1}, "VEC2", 2);
  nlohmann::json bare = b.doc["meshes"][0]["primitives"][0];
  b.doc["meshes"][0]["primitives"] = {textured, bare};
  const int pv = b.view(png.data(), png.size());
  b.doc["images"] = {{{"bufferView", pv}, {"mimeType", "image/png"}}};
  b.doc["textures"] = {{{"source", 0}}};
  b.doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 0}};
  b.write_glb(dir.file("uvless.glb"));
  Scene s;
  load_gltf(dir.file("uvless.glb"), s);
  ASSERT_EQ(s.meshes.size(), 2u);
  const auto &m0 = s.materials[std::size_t(s.meshes[0].material)], &m1 = s.materials[std::size_t(s.meshes[1].material)];
  EXPECT_EQ(m0.albedo_texture, 0);
  EXPECT_EQ(m1.albedo_texture, -1);
  EXPECT_EQ(m1.name, "paint (untextured)");
  EXPECT_EQ(m1.albedo, glm::vec3(0.25f, 0.5f, 0.75f));
  ASSERT_EQ(s.notices.size(), 1u);
  EXPECT_NE(s.notices[0].find("uvless.glb: mesh 0 'quad' primitive 1 has no TEXCOORD_0"), std::string::npos) << s.notices[0];
  EXPECT_NE(s.notices[0].find("baseColorTexture"), std::string::npos) << s.notices[0];
  // What a renderer sees: factor x texture (red) on the first primitive, the factor alone on the second.
  const auto posed = softgi::scene::evaluate(s, 0.0);
  ASSERT_EQ(posed.objects.size(), 2u);
  for (const auto& o : posed.objects) {
    const glm::vec3 albedo = softgi::scene::surface_albedo(s, o, 0, 0.3f, 0.3f);
    // The textured primitive's albedo depends on the point; the other's is its factor everywhere.
    glm::vec3 constant(-1.0f);
    const bool uniform = softgi::scene::constant_albedo(s, o, constant);
    if (o.mesh == 0) {
      EXPECT_EQ(albedo, glm::vec3(0.25f, 0.0f, 0.0f));
      EXPECT_FALSE(uniform);
    } else {
      EXPECT_EQ(albedo, glm::vec3(0.25f, 0.5f, 0.75f));
      EXPECT_TRUE(uniform);
      EXPECT_EQ(constant, albedo);
    }
  }
  EXPECT_NO_THROW(softgi::scene::validate(s));
}

// ---- JSON nesting depth ----

// The quad (its buffer in NAME.bin) with `arrays` nested arrays as the asset's extras: with the
// document's own object and "asset" that is arrays + 2 levels. Written as NAME.gltf and, the same
// JSON in a GLB's JSON chunk, as NAME.glb.
void write_nested_quad(const ScratchDir& dir, const std::string& name, int arrays) {
  GltfBuilder b;
  add_quad_mesh(b, true, false);
  b.write_gltf(dir.file(name + ".gltf"), name + ".bin");
  b.doc["asset"]["extras"] = "NESTING";
  std::string json = b.doc.dump();
  json.replace(json.find("\"NESTING\""), 9, std::string(std::size_t(arrays), '[') + std::string(std::size_t(arrays), ']'));
  softgi::test::write_text(dir.file(name + ".gltf"), json);
  while (json.size() % 4 != 0) json.push_back(' ');
  std::vector<unsigned char> glb;
  auto u32 = [&glb](std::uint32_t x) {
    for (int i = 0; i < 4; ++i) glb.push_back(static_cast<unsigned char>(x >> (8 * i)));
  };
  u32(0x46546C67);  // "glTF", version 2, total length, then the JSON chunk
  u32(2);
  u32(std::uint32_t(20 + json.size()));
  u32(std::uint32_t(json.size()));
  u32(0x4E4F534A);
  glb.insert(glb.end(), json.begin(), json.end());
  softgi::test::write_bytes(dir.file(name + ".glb"), glb);
}

TEST(io_gltf, JsonNestedTooDeepIsAnErrorInGltfAndGlb) {
  ScratchDir dir;
  // 20000 levels used to overflow the stack inside tinygltf; 63 arrays make 65 levels, one past the
  // limit of 64.
  for (const int arrays : {20000, 63}) {
    write_nested_quad(dir, "deep", arrays);
    for (const auto& [file, part] : {std::pair<std::string, std::string>{"deep.gltf", "the glTF JSON"},
                                     std::pair<std::string, std::string>{"deep.glb", "the GLB JSON chunk"}}) {
      Scene s;
      const std::string e = error_of([&] { load_gltf(dir.file(file), s); });
      EXPECT_NE(e.find(file + ": " + part + " is nested deeper than 64 levels"), std::string::npos) << arrays << " arrays: " << e;
    }
  }
  // 62 arrays: exactly 64 levels, which load.
  write_nested_quad(dir, "ok", 62);
  for (const char* file : {"ok.gltf", "ok.glb"}) {
    Scene s;
    EXPECT_NO_THROW(load_gltf(dir.file(file), s)) << file;
    EXPECT_EQ(s.meshes.size(), 1u) << file;
  }
}

// ---- Draco ----

// UV sphere as a triangle soup, encoded by draco::Encoder with quantised positions and normals.
struct DracoSphere {
  std::vector<unsigned char> bytes;
  int pos_id = -1, nrm_id = -1, points = 0, faces = 0;
};
constexpr float kSphereRadius = 2.0f;
constexpr int kPositionBits = 14, kNormalBits = 10;

DracoSphere encode_sphere(int seg, int rings) {
  std::vector<glm::vec3> tri;
  auto p = [&](int i, int j) {
    const float th = 3.14159265f * float(i) / float(rings), ph = 6.2831853f * float(j) / float(seg);
    return glm::vec3(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
  };
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < seg; ++j) {
      if (i != 0) tri.insert(tri.end(), {p(i, j), p(i, j + 1), p(i + 1, j + 1)});
      if (i != rings - 1) tri.insert(tri.end(), {p(i, j), p(i + 1, j + 1), p(i + 1, j)});
    }
  }
  const int nf = int(tri.size() / 3);
  draco::TriangleSoupMeshBuilder mb;
  mb.Start(nf);
  const int pa = mb.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  const int na = mb.AddAttribute(draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32);
  for (int f = 0; f < nf; ++f) {
    glm::vec3 q[3], n[3];
    for (int k = 0; k < 3; ++k) {
      n[k] = tri[std::size_t(3 * f + k)];
      q[k] = kSphereRadius * n[k];
    }
    mb.SetAttributeValuesForFace(pa, draco::FaceIndex(f), &q[0], &q[1], &q[2]);
    mb.SetAttributeValuesForFace(na, draco::FaceIndex(f), &n[0], &n[1], &n[2]);
  }
  std::unique_ptr<draco::Mesh> mesh = mb.Finalize();
  draco::Encoder enc;
  enc.SetAttributeQuantization(draco::GeometryAttribute::POSITION, kPositionBits);
  enc.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, kNormalBits);
  draco::EncoderBuffer buf;
  const draco::Status st = enc.EncodeMeshToBuffer(*mesh, &buf);
  EXPECT_TRUE(st.ok()) << st.error_msg_string();
  DracoSphere out;
  out.bytes.assign(buf.data(), buf.data() + buf.size());
  out.pos_id = int(mesh->attribute(pa)->unique_id());
  out.nrm_id = int(mesh->attribute(na)->unique_id());
  out.points = int(mesh->num_points());
  out.faces = nf;
  return out;
}

TEST(io_gltf, DracoCompressedPrimitiveDecodes) {
  ScratchDir dir;
  const DracoSphere d = encode_sphere(24, 12);
  ASSERT_FALSE(d.bytes.empty());
  GltfBuilder b;
  const int view = b.view(d.bytes.data(), d.bytes.size());
  // Accessors without bufferView: the data lives in the Draco stream (KHR_draco_mesh_compression).
  b.doc["accessors"] = {{{"componentType", 5126}, {"count", d.points}, {"type", "VEC3"}},
                        {{"componentType", 5126}, {"count", d.points}, {"type", "VEC3"}},
                        {{"componentType", 5125}, {"count", 3 * d.faces}, {"type", "SCALAR"}}};
  nlohmann::json prim = {
      {"attributes", {{"POSITION", 0}, {"NORMAL", 1}}},
      {"indices", 2},
      {"extensions",
       {{"KHR_draco_mesh_compression", {{"bufferView", view}, {"attributes", {{"POSITION", d.pos_id}, {"NORMAL", d.nrm_id}}}}}}}};
  b.doc["meshes"] = {{{"name", "ball"}, {"primitives", {prim}}}};
  b.doc["nodes"] = {{{"mesh", 0}}};
  b.doc["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  b.doc["extensionsRequired"] = {"KHR_draco_mesh_compression"};
  b.write_glb(dir.file("draco.glb"));

  Scene s;
  load_gltf(dir.file("draco.glb"), s);
  ASSERT_EQ(s.meshes.size(), 1u);
  const auto& m = s.meshes[0];
  EXPECT_EQ(int(m.positions.size()), d.points);
  EXPECT_EQ(int(m.triangles.size()), d.faces);
  // Quantisation to kPositionBits over the bounding box (side 2r): half a step per axis, sqrt(3) in length.
  const float pos_tol = std::sqrt(3.0f) * 0.5f * (2.0f * kSphereRadius) / float((1 << kPositionBits) - 1);
  // Octahedral normal quantisation at kNormalBits: a few steps of 2^-(bits-1) in angle (loose bound).
  const float nrm_tol = 4.0f / float(1 << (kNormalBits - 1));
  for (std::size_t i = 0; i < m.positions.size(); ++i) {
    EXPECT_NEAR(glm::length(m.positions[i]), kSphereRadius, pos_tol) << "vertex " << i;
    EXPECT_LT(glm::length(m.normals[i] - m.positions[i] / kSphereRadius), nrm_tol + pos_tol) << "vertex " << i;
  }
  // Winding survives: every triangle faces outwards.
  for (const auto& t : m.triangles) {
    const glm::vec3 n = glm::cross(m.positions[t[1]] - m.positions[t[0]], m.positions[t[2]] - m.positions[t[0]]);
    EXPECT_GT(glm::dot(n, m.positions[t[0]] + m.positions[t[1]] + m.positions[t[2]]), 0.0f);
  }
  EXPECT_NO_THROW(softgi::scene::validate(s));
}

TEST(io_gltf, DracoCountMismatchIsAnError) {
  ScratchDir dir;
  const DracoSphere d = encode_sphere(8, 4);
  GltfBuilder b;
  const int view = b.view(d.bytes.data(), d.bytes.size());
  b.doc["accessors"] = {{{"componentType", 5126}, {"count", d.points + 1}, {"type", "VEC3"}},
                        {{"componentType", 5126}, {"count", d.points + 1}, {"type", "VEC3"}}};
  b.doc["meshes"] = {{{"primitives",
                       {{{"attributes", {{"POSITION", 0}, {"NORMAL", 1}}},
                         {"extensions",
                          {{"KHR_draco_mesh_compression",
                            {{"bufferView", view}, {"attributes", {{"POSITION", d.pos_id}, {"NORMAL", d.nrm_id}}}}}}}}}}}};
  b.doc["nodes"] = {{{"mesh", 0}}};
  b.write_glb(dir.file("mismatch.glb"));
  Scene s;
  const std::string e = error_of([&] { load_gltf(dir.file("mismatch.glb"), s); });
  EXPECT_NE(e.find("mismatch.glb: mesh 0 primitive 0: KHR_draco_mesh_compression"), std::string::npos) << e;
  EXPECT_NE(e.find("Draco decoded " + std::to_string(d.points) + " points"), std::string::npos) << e;
}

TEST(io_gltf, CorruptDracoStreamIsAnError) {
  ScratchDir dir;
  DracoSphere d = encode_sphere(8, 4);
  d.bytes.resize(d.bytes.size() / 2);
  GltfBuilder b;
  const int view = b.view(d.bytes.data(), d.bytes.size());
  b.doc["accessors"] = {{{"componentType", 5126}, {"count", d.points}, {"type", "VEC3"}},
                        {{"componentType", 5126}, {"count", d.points}, {"type", "VEC3"}}};
  b.doc["meshes"] = {{{"primitives",
                       {{{"attributes", {{"POSITION", 0}, {"NORMAL", 1}}},
                         {"extensions",
                          {{"KHR_draco_mesh_compression",
                            {{"bufferView", view}, {"attributes", {{"POSITION", d.pos_id}, {"NORMAL", d.nrm_id}}}}}}}}}}}};
  b.doc["nodes"] = {{{"mesh", 0}}};
  b.write_glb(dir.file("corrupt.glb"));
  Scene s;
  const std::string e = error_of([&] { load_gltf(dir.file("corrupt.glb"), s); });
  EXPECT_NE(e.find("corrupt.glb: mesh 0 primitive 0: KHR_draco_mesh_compression: Draco decoding failed"), std::string::npos)
      << e;
}

TEST(io_gltf, UnsupportedRequiredExtensionIsAnError) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, true);
  b.doc["extensionsRequired"] = {"KHR_texture_transform"};
  b.write_glb(dir.file("ext.glb"));
  Scene s;
  const std::string e = error_of([&] { load_gltf(dir.file("ext.glb"), s); });
  EXPECT_NE(e.find("ext.glb: requires extension KHR_texture_transform"), std::string::npos) << e;
}

// ---- node transforms out of range ----

// A finite float scale of 1e30 once overflowed the bounds of the bare-glTF scene and was reported
// as "camera: position/target/up must be finite"; it is now refused at the node, naming it.
TEST(io_gltf, NodeScaleOf1e30IsAnErrorNamingTheNode) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, true);
  b.doc["nodes"][0]["scale"] = {1e30, 1e30, 1e30};
  b.write_glb(dir.file("huge.glb"));
  const std::string expect = "huge.glb: node 0 'quad_node': scale[0] = 1e+30 is outside |scale| in [1e-06, 1e+06]";
  Scene s;
  std::string e = error_of([&] { load_gltf(dir.file("huge.glb"), s); });
  EXPECT_NE(e.find(expect), std::string::npos) << e;
  // The bare-glTF scene (softgi render FILE.glb, fit-proxies) reports the same, not the camera.
  e = error_of([&] { softgi::io::load_scene(dir.file("huge.glb")); });
  EXPECT_NE(e.find(expect), std::string::npos) << e;
  EXPECT_EQ(e.find("camera"), std::string::npos) << e;
  // The same scale as a matrix.
  b.doc["nodes"][0].erase("scale");
  b.doc["nodes"][0]["matrix"] = {1e30, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  b.write_glb(dir.file("huge_matrix.glb"));
  e = error_of([&] { load_gltf(dir.file("huge_matrix.glb"), s); });
  EXPECT_NE(e.find("huge_matrix.glb: node 0 'quad_node': matrix scale[0] = 1e+30"), std::string::npos) << e;
}

TEST(io_gltf, SceneFileObjectScaleOf1e30IsAnErrorNamingTheObject) {
  ScratchDir dir;
  softgi::test::write_text(dir.file("huge.json"),
                           R"({"objects": [{"name": "ball", "mesh": "builtin:sphere", "transform": {"scale": 1e30}}]})");
  const std::string e = error_of([&] { softgi::io::load_scene_file(dir.file("huge.json")); });
  EXPECT_NE(e.find("huge.json: objects[0].transform.scale"), std::string::npos) << e;
  EXPECT_NE(e.find("1e+30"), std::string::npos) << e;
}

// Scales in range one by one can multiply out of range: the object's 1e5 times the file's node
// 1e5 is a world scale of 1e10, beyond 1e9 (scene::validate); the error names the node where the
// chain leaves the range and its parent.
TEST(io_gltf, ComposedNodeScaleOutOfRangeNamesTheNode) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, true);
  b.doc["nodes"][0]["scale"] = {1e5, 1e5, 1e5};
  b.doc["nodes"][0].erase("translation");
  b.write_glb(dir.file("big.glb"));
  softgi::test::write_text(dir.file("big.json"),
                           R"({"objects": [{"name": "holder", "mesh": "big.glb", "transform": {"scale": 1e5}}]})");
  const std::string e = error_of([&] { softgi::io::load_scene_file(dir.file("big.json")); });
  EXPECT_NE(e.find("big.json: node 'quad_node' (index 1): world axis scale 1e+10 is outside [1e-09, 1e+09]"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("under parent 'holder' (index 0)"), std::string::npos) << e;
  // 1e4 x 1e5 = 1e9 is in range.
  softgi::test::write_text(dir.file("ok.json"),
                           R"({"objects": [{"name": "holder", "mesh": "big.glb", "transform": {"scale": 1e4}}]})");
  EXPECT_NO_THROW(softgi::io::load_scene_file(dir.file("ok.json")));
}

TEST(io_gltf, ValidateNamesTheNodeWhoseWorldTransformLeavesTheRange) {
  Scene s;
  s.nodes.resize(1);  // an unrelated node first, so the index in the message is not 0
  const int base = int(s.nodes.size());
  for (int k = 0; k < 3; ++k) {
    softgi::scene::Node n;
    n.name = "level" + std::to_string(k);
    n.parent = k == 0 ? -1 : base + k - 1;
    n.scale = glm::vec3(1e4f);
    s.nodes.push_back(n);
  }
  // 1e4, 1e8, then 1e12 at level2.
  std::string e = error_of([&] { softgi::scene::validate(s); });
  EXPECT_NE(e.find("node 'level2' (index " + std::to_string(base + 2) + "): world axis scale 1e+12"), std::string::npos) << e;
  EXPECT_NE(e.find("under parent 'level1'"), std::string::npos) << e;
  s.nodes[std::size_t(base + 2)].scale = glm::vec3(1.0f);
  s.nodes[std::size_t(base + 2)].translation = glm::vec3(1e6f, 0.0f, 0.0f);  // 1e8 x 1e6 m
  e = error_of([&] { softgi::scene::validate(s); });
  EXPECT_NE(e.find("node 'level2' (index " + std::to_string(base + 2) + "): world translation (1e+14, 0, 0) is beyond 1e+12 m"),
            std::string::npos)
      << e;
  s.nodes[std::size_t(base + 2)].translation = glm::vec3(0.0f);
  EXPECT_NO_THROW(softgi::scene::validate(s));
  s.nodes[std::size_t(base)].scale = glm::vec3(1e30f);
  e = error_of([&] { softgi::scene::validate(s); });
  EXPECT_NE(e.find("node 'level0' (index " + std::to_string(base) + "): scale (1e+30, 1e+30, 1e+30): each |component| must be in [1e-06, 1e+06]"),
            std::string::npos)
      << e;
}

// ---- the proxy file's node index ----

// Nodes listed out of depth-first order: the file's nodes[0] 'second' is load_gltf's node 2, and
// the file's nodes[2] 'first' is load_gltf's node 1; both hold a mesh, so a proxy file read in the
// wrong numbering lands on the wrong object.
void add_out_of_order_nodes(GltfBuilder& b) {
  add_quad_mesh(b, true);
  b.doc["nodes"] = {{{"name", "second"}, {"mesh", 0}, {"translation", {3.0, 0.0, 0.0}}},
                    {{"name", "root"}, {"children", {2, 0}}},
                    {{"name", "first"}, {"mesh", 0}}};
  b.doc["scenes"] = {{{"nodes", {1}}}};
}

TEST(io_gltf, ProxyFileNodeIsLoadGltfsNumbering) {
  ScratchDir dir;
  GltfBuilder b;
  add_out_of_order_nodes(b);
  b.write_glb(dir.file("pair.glb"));
  Scene alone;
  load_gltf(dir.file("pair.glb"), alone);
  ASSERT_EQ(alone.nodes.size(), 3u);
  EXPECT_EQ(alone.nodes[0].name, "root");
  EXPECT_EQ(alone.nodes[1].name, "first");
  EXPECT_EQ(alone.nodes[2].name, "second");
  for (const auto& [k, name] : {std::pair<int, std::string>{1, "first"}, std::pair<int, std::string>{2, "second"}}) {
    softgi::scene::ProxySet ps;
    ps.name = name;
    ps.node = k;  // what `softgi fit-proxies` records for this node: its index in `alone`
    ps.spheres = {{glm::vec3(0.0f), 1.5f}};
    softgi::io::write_proxies_json(dir.file("pair_proxies.json"), ps);
    // A built-in object first (node 0) and the glTF object's own node (1): the file's nodes start at 2.
    softgi::test::write_text(dir.file("pair.json"), R"({"objects": [{"name": "ground", "mesh": "builtin:plane"},
        {"name": "pair", "mesh": "pair.glb", "proxies": "pair_proxies.json"}]})");
    const Scene s = softgi::io::load_scene_file(dir.file("pair.json"));
    ASSERT_EQ(s.proxies.size(), 1u);
    const int node = s.proxies[0].node;
    ASSERT_GE(node, 0);
    EXPECT_EQ(s.nodes[std::size_t(node)].name, name) << "proxy node " << k;
    EXPECT_GE(s.nodes[std::size_t(node)].mesh, 0);
  }
}

// The real asset: Stanford bunny from @pmndrs/assets (KHR_draco_mesh_compression).
TEST(io_gltf, BunnyAssetHasKnownVertexCount) {
  const std::string path = softgi::scene::assets_dir() + "/models/bunny.glb";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "asset set absent (" << path << "); run scripts/fetch-assets.sh";
  Scene s;
  load_gltf(path, s);
  std::size_t vertices = 0, triangles = 0;
  for (const auto& m : s.meshes) {
    vertices += m.positions.size();
    triangles += m.triangles.size();
  }
  // 2826 vertices: docs/toolchain notes for the @pmndrs/assets bunny (and its POSITION accessor).
  EXPECT_EQ(vertices, 2826u);
  // 16944 indices in the file; Draco keeps every face, the loader drops only zero-area ones.
  EXPECT_LE(triangles, 16944u / 3);
  EXPECT_GT(triangles, 16944u / 3 * 99 / 100);
  EXPECT_NO_THROW(softgi::scene::validate(s));
}

TEST(io_gltf, SuzanneAssetHasKnownVertexCount) {
  const std::string path = softgi::scene::assets_dir() + "/models/suzi.glb";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "asset set absent (" << path << "); run scripts/fetch-assets.sh";
  Scene s;
  load_gltf(path, s);
  ASSERT_EQ(s.meshes.size(), 1u);
  // 7503 vertices and 44526 indices: the file's POSITION and indices accessors.
  EXPECT_EQ(s.meshes[0].positions.size(), 7503u);
  EXPECT_LE(s.meshes[0].triangles.size(), 44526u / 3);
  EXPECT_GT(s.meshes[0].triangles.size(), 44526u / 3 * 99 / 100);
  EXPECT_NO_THROW(softgi::scene::validate(s));
}

}  // namespace
