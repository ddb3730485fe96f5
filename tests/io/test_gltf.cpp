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

TEST(io_gltf, MissingNormalsIsAnErrorNamingMeshAndPrimitive) {
  ScratchDir dir;
  GltfBuilder b;
  add_quad_mesh(b, false);
  b.write_glb(dir.file("nonormals.glb"));
  Scene s;
  const std::string e = error_of([&] { load_gltf(dir.file("nonormals.glb"), s); });
  EXPECT_NE(e.find("nonormals.glb"), std::string::npos) << e;
  EXPECT_NE(e.find("mesh 0 'quad' primitive 0"), std::string::npos) << e;
  EXPECT_NE(e.find("NORMAL"), std::string::npos) << e;
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
