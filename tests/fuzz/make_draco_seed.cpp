// Writes tests/fuzz/corpus_gltf/valid_draco.glb: an octahedron whose POSITION, NORMAL and
// TEXCOORD_0 are in a KHR_draco_mesh_compression stream, the seed through which the glTF fuzz
// target reaches the Draco decoding of io::load_gltf. Not part of any build; run once:
//
//   g++ -std=c++20 tests/fuzz/make_draco_seed.cpp -ldraco -o /tmp/make_draco_seed && /tmp/make_draco_seed tests/fuzz/corpus_gltf
#include <draco/compression/encode.h>
#include <draco/core/encoder_buffer.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUTPUT_DIR\n", argv[0]);
    return 2;
  }
  // The 8 faces of the octahedron |x| + |y| + |z| = 1, counter-clockwise seen from outside.
  const float v[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  const int f[8][3] = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  draco::TriangleSoupMeshBuilder mb;
  mb.Start(8);
  const int pa = mb.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  const int na = mb.AddAttribute(draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32);
  const int ta = mb.AddAttribute(draco::GeometryAttribute::TEX_COORD, 2, draco::DT_FLOAT32);
  for (int t = 0; t < 8; ++t) {
    const float* p[3] = {v[f[t][0]], v[f[t][1]], v[f[t][2]]};
    float uv[3][2];
    for (int k = 0; k < 3; ++k) {
      uv[k][0] = 0.5f + 0.5f * p[k][0];
      uv[k][1] = 0.5f + 0.5f * p[k][2];
    }
    // Vertex normals of the octahedron's corners are the corners themselves.
    mb.SetAttributeValuesForFace(pa, draco::FaceIndex(t), p[0], p[1], p[2]);
    mb.SetAttributeValuesForFace(na, draco::FaceIndex(t), p[0], p[1], p[2]);
    mb.SetAttributeValuesForFace(ta, draco::FaceIndex(t), uv[0], uv[1], uv[2]);
  }
  std::unique_ptr<draco::Mesh> mesh = mb.Finalize();
  draco::Encoder enc;
  enc.SetAttributeQuantization(draco::GeometryAttribute::POSITION, 11);
  enc.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, 8);
  enc.SetAttributeQuantization(draco::GeometryAttribute::TEX_COORD, 10);
  draco::EncoderBuffer buf;
  if (!enc.EncodeMeshToBuffer(*mesh, &buf).ok()) return 1;
  std::vector<unsigned char> bin(buf.data(), buf.data() + buf.size());
  while (bin.size() % 4 != 0) bin.push_back(0);
  const auto points = std::to_string(mesh->num_points());
  const std::string json =
      R"({"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],)"
      R"("extensionsRequired":["KHR_draco_mesh_compression"],"buffers":[{"byteLength":)" +
      std::to_string(bin.size()) + R"(}],"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":)" +
      std::to_string(buf.size()) + R"(}],"accessors":[{"componentType":5126,"count":)" + points +
      R"(,"type":"VEC3","min":[-1,-1,-1],"max":[1,1,1]},{"componentType":5126,"count":)" + points +
      R"(,"type":"VEC3"},{"componentType":5126,"count":)" + points +
      R"(,"type":"VEC2"},{"componentType":5125,"count":24,"type":"SCALAR"}],)"
      R"("meshes":[{"name":"octahedron","primitives":[{"attributes":{"POSITION":0,"NORMAL":1,"TEXCOORD_0":2},)"
      R"("indices":3,"extensions":{"KHR_draco_mesh_compression":{"bufferView":0,"attributes":{"POSITION":)" +
      std::to_string(mesh->attribute(pa)->unique_id()) + R"(,"NORMAL":)" +
      std::to_string(mesh->attribute(na)->unique_id()) + R"(,"TEXCOORD_0":)" +
      std::to_string(mesh->attribute(ta)->unique_id()) +
      R"(}}}}]}],"nodes":[{"name":"octahedron","mesh":0}],"scenes":[{"nodes":[0]}],"scene":0})";
  std::string js = json;
  while (js.size() % 4 != 0) js.push_back(' ');
  std::vector<unsigned char> out;
  auto u32 = [&out](std::uint32_t x) {
    for (int i = 0; i < 4; ++i) out.push_back(static_cast<unsigned char>(x >> (8 * i)));
  };
  u32(0x46546C67);
  u32(2);
  u32(std::uint32_t(12 + 8 + js.size() + 8 + bin.size()));
  u32(std::uint32_t(js.size()));
  u32(0x4E4F534A);
  out.insert(out.end(), js.begin(), js.end());
  u32(std::uint32_t(bin.size()));
  u32(0x004E4942);
  out.insert(out.end(), bin.begin(), bin.end());
  std::ofstream(std::string(argv[1]) + "/valid_draco.glb", std::ios::binary)
      .write(reinterpret_cast<const char*>(out.data()), std::streamsize(out.size()));
  return 0;
}
