// glTF 2.0 / GLB loading through tinygltf 2.7 (Debian's shared libtinygltf) and Draco 1.5.
//
// Debian's libtinygltf.so already holds the implementation (built with stb_image and nlohmann-json,
// without Draco), so this file includes only the declarations: TINYGLTF_IMPLEMENTATION must NOT be
// defined, and neither may TINYGLTF_NO_STB_IMAGE / _NO_STB_IMAGE_WRITE / _NO_FS, which change the
// layout of tinygltf::TinyGLTF and would break the ABI with the shared library.
//
// KHR_draco_mesh_compression is decoded here. tinygltf 2.7 rejects a primitive whose `indices`
// accessor has no bufferView (always the case for Draco primitives), so the JSON is rewritten before
// tinygltf sees it: the `indices` of Draco primitives are moved to a side table.
#include "softgi/io/gltf.hpp"

#include <tiny_gltf.h>

#include <draco/compression/decode.h>
#include <draco/core/decoder_buffer.h>
#include <draco/mesh/mesh.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <glm/gtc/type_ptr.hpp>

namespace softgi::io {
namespace {

namespace fs = std::filesystem;

// Sizes beyond these are treated as corrupt files rather than models.
constexpr std::size_t kMaxFileBytes = std::size_t(2) << 30;    // 2 GiB
constexpr std::size_t kMaxAccessorCount = std::size_t(1) << 27;  // 134M elements
constexpr std::size_t kMaxStride = 4096;
// A node matrix whose rotation part deviates from orthonormal by more than this (after dividing
// out the column lengths) has shear, which Node's TRS cannot represent.
constexpr double kShearTolerance = 1e-3;
// Triangles with |cross| <= this * (longest edge)^2 are dropped: the same zero-area test as
// scene::validate (core/src/scene/scene.cpp), which would otherwise reject the whole mesh.
constexpr float kZeroAreaRelative = 1e-7f;
// Node scale limits per axis, the ones scene::validate applies (core/src/scene/scene.cpp), checked
// here so that the error names the node as the file numbers it: beyond them the input is broken.
constexpr double kMinScale = 1e-6, kMaxScaleAbs = 1e6;
// tinygltf 2.7 turns the parsed JSON into tinygltf::Value by recursion, so a document nested some
// ten thousand levels deep overflows the stack inside it. Real glTF needs well under 10 levels
// (extras included); scene and proxy files refuse the same depth (core/src/io/scene_file.cpp).
constexpr int kMaxJsonDepth = 64;

constexpr std::uint32_t kGlbMagic = 0x46546C67;      // "glTF"
constexpr std::uint32_t kGlbChunkJson = 0x4E4F534A;  // "JSON"
constexpr const char* kDraco = "KHR_draco_mesh_compression";

struct Values {
  std::size_t count = 0;
  int ncomp = 0;
  std::vector<double> v;  // count * ncomp
  double at(std::size_t i, int k) const { return v[i * std::size_t(ncomp) + std::size_t(k)]; }
};

std::string quoted(const std::string& s) { return "'" + s + "'"; }

struct Loader {
  std::string path;
  tinygltf::Model model;
  scene::Scene& scene;
  // Draco primitives' `indices` accessors, keyed by (mesh, primitive); removed from the JSON.
  std::map<std::pair<int, int>, int> draco_indices;

  std::map<int, std::vector<int>> mesh_map;  // glTF mesh -> scene meshes (one per primitive)
  std::map<int, int> material_map;           // glTF material -> scene material
  std::map<int, int> untextured_map;         // scene material -> its copy without albedo texture
  std::map<int, int> texture_map;            // glTF texture -> scene texture
  std::map<int, int> skin_map;               // glTF skin -> scene skin
  std::vector<int> node_map;                 // glTF node -> scene node (-1: not in the imported scene)
  int default_material = -1;

  Loader(std::string p, scene::Scene& s) : path(std::move(p)), scene(s) {}

  [[noreturn]] void fail(const std::string& what) const { throw std::runtime_error(path + ": " + what); }

  std::string mesh_label(int mesh, int prim) const {
    const std::string& n = model.meshes[std::size_t(mesh)].name;
    return "mesh " + std::to_string(mesh) + (n.empty() ? "" : " " + quoted(n)) + " primitive " + std::to_string(prim);
  }
  std::string node_label(int node) const {
    const std::string& n = model.nodes[std::size_t(node)].name;
    return "node " + std::to_string(node) + (n.empty() ? "" : " " + quoted(n));
  }

  // ---- file reading ----

  std::vector<unsigned char> read_file() const {
    std::error_code ec;
    if (!fs::exists(path, ec)) fail("no such file");
    if (fs::is_directory(path, ec)) fail("is a directory, not a glTF file");
    std::ifstream in(path, std::ios::binary);
    if (!in) fail("cannot open for reading");
    in.seekg(0, std::ios::end);
    const std::streamoff size = in.tellg();
    if (size < 0) fail("cannot determine the file size");
    if (std::size_t(size) > kMaxFileBytes) fail("file of " + std::to_string(size) + " bytes is larger than the 2 GiB limit");
    in.seekg(0, std::ios::beg);
    std::vector<unsigned char> bytes(static_cast<std::size_t>(size));
    if (size > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), size)) fail("read error");
    if (bytes.empty()) fail("empty file");
    return bytes;
  }

  static std::uint32_t u32(const unsigned char* p) {
    return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
  }
  static void put_u32(std::vector<unsigned char>& out, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) out.push_back(static_cast<unsigned char>(v >> (8 * i)));
  }

  // Refuses JSON nested deeper than kMaxJsonDepth before any JSON parser sees it: a lexical scan
  // that counts brackets outside strings (an unbalanced or otherwise broken document is left for
  // tinygltf to report).
  void check_json_depth(const char* text, std::size_t size, const char* what) const {
    int depth = 0;
    bool in_string = false, escaped = false;
    for (std::size_t i = 0; i < size; ++i) {
      const char c = text[i];
      if (in_string) {
        if (escaped) {
          escaped = false;
        } else if (c == '\\') {
          escaped = true;
        } else if (c == '"') {
          in_string = false;
        }
      } else if (c == '"') {
        in_string = true;
      } else if (c == '[' || c == '{') {
        if (++depth > kMaxJsonDepth) {
          fail(std::string(what) + " is nested deeper than " + std::to_string(kMaxJsonDepth) + " levels (at byte " +
               std::to_string(i) + ")");
        }
      } else if ((c == ']' || c == '}') && depth > 0) {
        --depth;
      }
    }
  }

  // Moves `indices` of Draco-compressed primitives into draco_indices (see the file comment).
  // Returns the JSON unchanged when there is nothing to move or it does not parse (tinygltf then
  // reports the syntax error).
  std::string rewrite_draco_json(const std::string& text) {
    if (text.find(kDraco) == std::string::npos) return text;
    nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
    if (j.is_discarded() || !j.is_object()) return text;
    auto meshes = j.find("meshes");
    if (meshes == j.end() || !meshes->is_array()) return text;
    bool changed = false;
    for (std::size_t m = 0; m < meshes->size(); ++m) {
      auto& mesh = (*meshes)[m];
      if (!mesh.is_object()) continue;
      auto prims = mesh.find("primitives");
      if (prims == mesh.end() || !prims->is_array()) continue;
      for (std::size_t p = 0; p < prims->size(); ++p) {
        auto& prim = (*prims)[p];
        if (!prim.is_object()) continue;
        auto ext = prim.find("extensions");
        if (ext == prim.end() || !ext->is_object() || !ext->contains(kDraco)) continue;
        auto idx = prim.find("indices");
        if (idx == prim.end()) continue;
        if (!idx->is_number_integer()) fail(mesh_label_raw(int(m), int(p)) + ": `indices` is not an integer");
        draco_indices[{int(m), int(p)}] = idx->get<int>();
        prim.erase("indices");
        changed = true;
      }
    }
    return changed ? j.dump() : text;
  }
  static std::string mesh_label_raw(int mesh, int prim) {
    return "mesh " + std::to_string(mesh) + " primitive " + std::to_string(prim);
  }

  void load_model() {
    std::vector<unsigned char> bytes = read_file();
    std::string base_dir = fs::path(path).parent_path().string();
    if (base_dir.empty()) base_dir = ".";
    tinygltf::TinyGLTF gltf;
    std::string err, warn;
    bool ok = false;
    if (bytes.size() >= 4 && u32(bytes.data()) == kGlbMagic) {
      // GLB: 12-byte header, a JSON chunk, an optional BIN chunk (glTF 2.0 spec, section 4.4).
      if (bytes.size() < 20) fail("truncated GLB: " + std::to_string(bytes.size()) + " bytes, the header needs 20");
      const std::uint32_t version = u32(bytes.data() + 4), length = u32(bytes.data() + 8);
      if (version != 2) fail("GLB version " + std::to_string(version) + " (only glTF 2.0 is supported)");
      if (length > bytes.size()) {
        fail("truncated GLB: the header declares " + std::to_string(length) + " bytes but the file has " +
             std::to_string(bytes.size()));
      }
      const std::uint32_t json_len = u32(bytes.data() + 12), json_type = u32(bytes.data() + 16);
      if (json_type != kGlbChunkJson) fail("malformed GLB: the first chunk is not JSON");
      if (std::uint64_t(json_len) + 20 > length) {
        fail("truncated GLB: the JSON chunk declares " + std::to_string(json_len) + " bytes, beyond the file's " +
             std::to_string(length));
      }
      // tinygltf bounds the BIN chunk's payload by the file length without the chunk's own 8-byte
      // header, so a payload declared up to 8 bytes too long would be copied from beyond the file.
      const std::uint64_t bin_begin = 20 + std::uint64_t(json_len);
      if (bin_begin < length) {
        if (bin_begin + 8 > length) {
          fail("truncated GLB: " + std::to_string(length - bin_begin) +
               " bytes follow the JSON chunk, too few for a chunk header (8)");
        }
        const std::uint32_t bin_len = u32(bytes.data() + bin_begin);
        if (bin_begin + 8 + bin_len > length) {
          fail("truncated GLB: the BIN chunk declares " + std::to_string(bin_len) + " bytes but " +
               std::to_string(length - bin_begin - 8) + " follow its header");
        }
      }
      check_json_depth(reinterpret_cast<const char*>(bytes.data() + 20), json_len, "the GLB JSON chunk");
      const std::string json(reinterpret_cast<const char*>(bytes.data() + 20), json_len);
      std::string rewritten = rewrite_draco_json(json);
      if (rewritten != json) {
        while (rewritten.size() % 4 != 0) rewritten.push_back(' ');
        std::vector<unsigned char> glb;
        const std::size_t rest_begin = 20 + std::size_t(json_len);
        const std::size_t rest = length - rest_begin;
        glb.reserve(20 + rewritten.size() + rest);
        put_u32(glb, kGlbMagic);
        put_u32(glb, 2);
        put_u32(glb, std::uint32_t(20 + rewritten.size() + rest));
        put_u32(glb, std::uint32_t(rewritten.size()));
        put_u32(glb, kGlbChunkJson);
        glb.insert(glb.end(), rewritten.begin(), rewritten.end());
        glb.insert(glb.end(), bytes.begin() + std::ptrdiff_t(rest_begin), bytes.begin() + std::ptrdiff_t(length));
        bytes.swap(glb);
      } else {
        bytes.resize(length);
      }
      ok = gltf.LoadBinaryFromMemory(&model, &err, &warn, bytes.data(), static_cast<unsigned int>(bytes.size()),
                                     base_dir);
    } else {
      check_json_depth(reinterpret_cast<const char*>(bytes.data()), bytes.size(), "the glTF JSON");
      const std::string json = rewrite_draco_json(std::string(bytes.begin(), bytes.end()));
      ok = gltf.LoadASCIIFromString(&model, &err, &warn, json.data(), static_cast<unsigned int>(json.size()),
                                    base_dir);
    }
    if (!ok) {
      while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
      fail("cannot parse glTF: " + (err.empty() ? std::string("unknown error") : err));
    }
    static const std::set<std::string> kSupportedRequired = {kDraco, "KHR_mesh_quantization"};
    for (const auto& ext : model.extensionsRequired) {
      if (!kSupportedRequired.count(ext)) fail("requires extension " + ext + ", which softgi does not support");
    }
  }

  // ---- accessors ----

  static double component(const unsigned char* p, int type, bool normalized) {
    switch (type) {
      case TINYGLTF_COMPONENT_TYPE_BYTE: {
        std::int8_t v;
        std::memcpy(&v, p, 1);
        return normalized ? std::max(double(v) / 127.0, -1.0) : double(v);
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: {
        std::uint8_t v;
        std::memcpy(&v, p, 1);
        return normalized ? double(v) / 255.0 : double(v);
      }
      case TINYGLTF_COMPONENT_TYPE_SHORT: {
        std::int16_t v;
        std::memcpy(&v, p, 2);
        return normalized ? std::max(double(v) / 32767.0, -1.0) : double(v);
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        std::uint16_t v;
        std::memcpy(&v, p, 2);
        return normalized ? double(v) / 65535.0 : double(v);
      }
      case TINYGLTF_COMPONENT_TYPE_INT: {
        std::int32_t v;
        std::memcpy(&v, p, 4);
        return double(v);
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
        std::uint32_t v;
        std::memcpy(&v, p, 4);
        return double(v);
      }
      case TINYGLTF_COMPONENT_TYPE_FLOAT: {
        float v;
        std::memcpy(&v, p, 4);
        return double(v);
      }
      case TINYGLTF_COMPONENT_TYPE_DOUBLE: {
        double v;
        std::memcpy(&v, p, 8);
        return v;
      }
      default:
        return 0.0;
    }
  }

  // Bytes [offset, offset + span) of buffer view `bv`, checked against the view and its buffer.
  const unsigned char* view_bytes(int bv, std::uint64_t offset, std::uint64_t span, const std::string& what) const {
    if (bv < 0 || std::size_t(bv) >= model.bufferViews.size()) fail(what + ": bufferView " + std::to_string(bv) + " does not exist");
    const auto& view = model.bufferViews[std::size_t(bv)];
    if (view.buffer < 0 || std::size_t(view.buffer) >= model.buffers.size()) {
      fail(what + ": bufferView " + std::to_string(bv) + " refers to missing buffer " + std::to_string(view.buffer));
    }
    const auto& buf = model.buffers[std::size_t(view.buffer)].data;
    if (std::uint64_t(view.byteOffset) + view.byteLength > buf.size()) {
      fail(what + ": bufferView " + std::to_string(bv) + " (offset " + std::to_string(view.byteOffset) + ", length " +
           std::to_string(view.byteLength) + ") runs past its buffer of " + std::to_string(buf.size()) + " bytes");
    }
    if (offset + span > view.byteLength) {
      fail(what + ": needs bytes [" + std::to_string(offset) + ", " + std::to_string(offset + span) + ") of bufferView " +
           std::to_string(bv) + ", which has " + std::to_string(view.byteLength));
    }
    return buf.data() + view.byteOffset + offset;
  }

  Values read_accessor(int index, const std::string& what) const {
    const std::string label = what + " (accessor " + std::to_string(index) + ")";
    if (index < 0 || std::size_t(index) >= model.accessors.size()) fail(label + ": accessor does not exist");
    const auto& acc = model.accessors[std::size_t(index)];
    const int ncomp = tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(acc.type));
    const int csize = tinygltf::GetComponentSizeInBytes(static_cast<std::uint32_t>(acc.componentType));
    if (ncomp <= 0) fail(label + ": unknown accessor type " + std::to_string(acc.type));
    if (csize <= 0) fail(label + ": unknown component type " + std::to_string(acc.componentType));
    if ((acc.type == TINYGLTF_TYPE_MAT2 || acc.type == TINYGLTF_TYPE_MAT3) && csize < 4) {
      fail(label + ": padded 8/16-bit matrices are not supported");
    }
    if (acc.count > kMaxAccessorCount) fail(label + ": absurd element count " + std::to_string(acc.count));
    Values out;
    out.count = acc.count;
    out.ncomp = ncomp;
    out.v.assign(acc.count * std::size_t(ncomp), 0.0);
    const std::size_t elem = std::size_t(ncomp) * std::size_t(csize);
    if (acc.bufferView >= 0 && acc.count > 0) {
      if (std::size_t(acc.bufferView) >= model.bufferViews.size()) {
        fail(label + ": bufferView " + std::to_string(acc.bufferView) + " does not exist");
      }
      const auto& view = model.bufferViews[std::size_t(acc.bufferView)];
      const std::size_t stride = view.byteStride ? view.byteStride : elem;
      if (stride < elem || stride > kMaxStride) {
        fail(label + ": byteStride " + std::to_string(stride) + " is not in [" + std::to_string(elem) + ", " +
             std::to_string(kMaxStride) + "]");
      }
      const std::uint64_t span = std::uint64_t(stride) * (acc.count - 1) + elem;
      const unsigned char* base = view_bytes(acc.bufferView, acc.byteOffset, span, label);
      for (std::size_t i = 0; i < acc.count; ++i) {
        for (int k = 0; k < ncomp; ++k) {
          out.v[i * std::size_t(ncomp) + std::size_t(k)] =
              component(base + i * stride + std::size_t(k) * std::size_t(csize), acc.componentType, acc.normalized);
        }
      }
    }
    if (acc.sparse.isSparse) {
      const auto& sp = acc.sparse;
      if (sp.count < 0 || std::size_t(sp.count) > acc.count) {
        fail(label + ": sparse count " + std::to_string(sp.count) + " exceeds the accessor's " + std::to_string(acc.count));
      }
      const int isize = tinygltf::GetComponentSizeInBytes(static_cast<std::uint32_t>(sp.indices.componentType));
      if (isize <= 0 || sp.indices.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT) {
        fail(label + ": bad sparse index component type " + std::to_string(sp.indices.componentType));
      }
      if (sp.indices.byteOffset < 0 || sp.values.byteOffset < 0) fail(label + ": negative sparse byteOffset");
      const std::size_t n = std::size_t(sp.count);
      const unsigned char* ip = view_bytes(sp.indices.bufferView, std::uint64_t(sp.indices.byteOffset),
                                           std::uint64_t(isize) * n, label + " sparse indices");
      const unsigned char* vp = view_bytes(sp.values.bufferView, std::uint64_t(sp.values.byteOffset),
                                           std::uint64_t(elem) * n, label + " sparse values");
      for (std::size_t s = 0; s < n; ++s) {
        const double target = component(ip + s * std::size_t(isize), sp.indices.componentType, false);
        if (target < 0 || target >= double(acc.count)) {
          fail(label + ": sparse index " + std::to_string(std::int64_t(target)) + " out of range");
        }
        const std::size_t t = std::size_t(target);
        for (int k = 0; k < ncomp; ++k) {
          out.v[t * std::size_t(ncomp) + std::size_t(k)] =
              component(vp + s * elem + std::size_t(k) * std::size_t(csize), acc.componentType, acc.normalized);
        }
      }
    }
    check_finite(out, label);
    return out;
  }

  void check_finite(const Values& v, const std::string& label) const {
    for (std::size_t i = 0; i < v.v.size(); ++i) {
      if (!std::isfinite(v.v[i])) {
        std::ostringstream s;
        s << label << ": element " << i / std::size_t(v.ncomp) << " component " << i % std::size_t(v.ncomp) << " is "
          << v.v[i];
        fail(s.str());
      }
    }
  }

  // ---- Draco ----

  // Decodes a KHR_draco_mesh_compression primitive: the attributes the extension names (read with
  // the component type, count and normalisation of the primitive's accessors, as the extension
  // specifies) and the triangle indices.
  void decode_draco(int mesh_index, int prim_index, const tinygltf::Value& ext, std::map<std::string, Values>& attrs,
                    std::vector<std::uint32_t>& indices) const {
    const std::string label = mesh_label(mesh_index, prim_index) + ": " + kDraco;
    const auto& prim = model.meshes[std::size_t(mesh_index)].primitives[std::size_t(prim_index)];
    if (!ext.IsObject() || !ext.Has("bufferView") || !ext.Get("bufferView").IsInt()) fail(label + ": missing bufferView");
    if (!ext.Has("attributes") || !ext.Get("attributes").IsObject()) fail(label + ": missing attributes");
    const int bv = ext.Get("bufferView").Get<int>();
    if (bv < 0 || std::size_t(bv) >= model.bufferViews.size()) fail(label + ": bufferView " + std::to_string(bv) + " does not exist");
    const auto& view = model.bufferViews[std::size_t(bv)];
    const unsigned char* data = view_bytes(bv, 0, view.byteLength, label);

    draco::DecoderBuffer buffer;
    buffer.Init(reinterpret_cast<const char*>(data), view.byteLength);
    draco::Decoder decoder;
    auto result = decoder.DecodeMeshFromBuffer(&buffer);
    if (!result.ok()) fail(label + ": Draco decoding failed: " + result.status().error_msg_string());
    const std::unique_ptr<draco::Mesh> dmesh = std::move(result).value();
    const std::size_t npoints = dmesh->num_points();

    const tinygltf::Value& amap = ext.Get("attributes");
    for (const std::string& name : amap.Keys()) {
      const tinygltf::Value& idv = amap.Get(name);
      if (!idv.IsInt()) fail(label + ": attribute " + name + " has a non-integer id");
      auto acc_it = prim.attributes.find(name);
      if (acc_it == prim.attributes.end()) {
        fail(label + ": attribute " + name + " has no accessor in the primitive's attributes");
      }
      if (acc_it->second < 0 || std::size_t(acc_it->second) >= model.accessors.size()) {
        fail(label + ": attribute " + name + " refers to missing accessor " + std::to_string(acc_it->second));
      }
      const auto& acc = model.accessors[std::size_t(acc_it->second)];
      const draco::PointAttribute* att = dmesh->GetAttributeByUniqueId(static_cast<std::uint32_t>(idv.Get<int>()));
      if (!att) fail(label + ": attribute " + name + ": Draco id " + std::to_string(idv.Get<int>()) + " not in the stream");
      const int ncomp = tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(acc.type));
      if (ncomp <= 0 || ncomp > 16) fail(label + ": attribute " + name + ": unknown accessor type " + std::to_string(acc.type));
      if (att->num_components() < ncomp) {
        fail(label + ": attribute " + name + " has " + std::to_string(int(att->num_components())) +
             " components in the Draco stream, the accessor needs " + std::to_string(ncomp));
      }
      if (acc.count != npoints) {
        fail(label + ": attribute " + name + ": accessor count " + std::to_string(acc.count) + " but Draco decoded " +
             std::to_string(npoints) + " points");
      }
      const bool draco_int = att->data_type() != draco::DT_FLOAT32 && att->data_type() != draco::DT_FLOAT64;
      // Integers the Draco stream leaves un-normalised take the glTF accessor's normalisation.
      const bool normalize = draco_int && !att->normalized() && acc.normalized;
      double scale = 1.0;
      if (normalize) {
        switch (acc.componentType) {
          case TINYGLTF_COMPONENT_TYPE_BYTE: scale = 1.0 / 127.0; break;
          case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: scale = 1.0 / 255.0; break;
          case TINYGLTF_COMPONENT_TYPE_SHORT: scale = 1.0 / 32767.0; break;
          case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: scale = 1.0 / 65535.0; break;
          default: fail(label + ": attribute " + name + ": normalized accessor of component type " +
                        std::to_string(acc.componentType));
        }
      }
      Values vals;
      vals.count = npoints;
      vals.ncomp = ncomp;
      vals.v.resize(npoints * std::size_t(ncomp));
      std::array<double, 16> tmp{};
      for (std::size_t i = 0; i < npoints; ++i) {
        const draco::AttributeValueIndex avi = att->mapped_index(draco::PointIndex(static_cast<std::uint32_t>(i)));
        if (!att->ConvertValue<double>(avi, static_cast<std::int8_t>(ncomp), tmp.data())) {
          fail(label + ": attribute " + name + ": cannot read value of point " + std::to_string(i));
        }
        for (int k = 0; k < ncomp; ++k) {
          double x = tmp[std::size_t(k)] * scale;
          if (normalize) x = std::max(x, -1.0);
          vals.v[i * std::size_t(ncomp) + std::size_t(k)] = x;
        }
      }
      check_finite(vals, label + ": attribute " + name);
      attrs[name] = std::move(vals);
    }
    indices.clear();
    indices.reserve(std::size_t(dmesh->num_faces()) * 3);
    for (draco::FaceIndex f(0); f < dmesh->num_faces(); ++f) {
      const draco::Mesh::Face& face = dmesh->face(f);
      for (int k = 0; k < 3; ++k) indices.push_back(face[k].value());
    }
    auto it = draco_indices.find({mesh_index, prim_index});
    if (it != draco_indices.end()) {
      if (it->second < 0 || std::size_t(it->second) >= model.accessors.size()) {
        fail(label + ": indices accessor " + std::to_string(it->second) + " does not exist");
      }
      if (model.accessors[std::size_t(it->second)].count != indices.size()) {
        fail(label + ": indices accessor count " + std::to_string(model.accessors[std::size_t(it->second)].count) +
             " but Draco decoded " + std::to_string(indices.size()) + " indices");
      }
    }
  }

  // ---- meshes ----

  scene::Mesh build_primitive(int mesh_index, int prim_index) {
    const auto& gmesh = model.meshes[std::size_t(mesh_index)];
    const auto& prim = gmesh.primitives[std::size_t(prim_index)];
    const std::string label = mesh_label(mesh_index, prim_index);
    const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN) {
      fail(label + ": unsupported primitive mode " + std::to_string(mode) + " (only triangles, strips and fans)");
    }

    std::map<std::string, Values> attrs;
    std::vector<std::uint32_t> indices;
    bool indexed = false;
    auto draco_ext = prim.extensions.find(kDraco);
    if (draco_ext != prim.extensions.end()) {
      decode_draco(mesh_index, prim_index, draco_ext->second, attrs, indices);
      indexed = true;
    }
    // Attributes outside the Draco stream (or all of them without Draco) come from accessors.
    for (const char* name : {"POSITION", "NORMAL", "TEXCOORD_0", "COLOR_0", "JOINTS_0", "WEIGHTS_0"}) {
      if (attrs.count(name)) continue;
      auto it = prim.attributes.find(name);
      if (it != prim.attributes.end()) attrs[name] = read_accessor(it->second, label + " " + name);
    }
    if (!indexed && prim.indices >= 0) {
      const Values iv = read_accessor(prim.indices, label + " indices");
      const auto& acc = model.accessors[std::size_t(prim.indices)];
      if (iv.ncomp != 1 || (acc.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
                            acc.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
                            acc.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)) {
        fail(label + ": indices must be scalar unsigned integers");
      }
      indices.resize(iv.count);
      for (std::size_t i = 0; i < iv.count; ++i) indices[i] = static_cast<std::uint32_t>(iv.v[i]);
      indexed = true;
    }

    auto pos_it = attrs.find("POSITION");
    if (pos_it == attrs.end()) fail(label + ": no POSITION attribute");
    auto nrm_it = attrs.find("NORMAL");
    // glTF 2.0 section 3.7.2.1: without NORMAL, "client implementations MUST calculate flat normals".
    const bool flat = nrm_it == attrs.end();
    const Values& pos = pos_it->second;
    if (pos.ncomp != 3) fail(label + ": POSITION must be VEC3");
    const std::size_t n = pos.count;
    if (n == 0) fail(label + ": no vertices");
    auto check_count = [&](const char* name, const Values& v) {
      if (v.count != n) {
        fail(label + ": " + name + " has " + std::to_string(v.count) + " elements, POSITION has " + std::to_string(n));
      }
    };

    scene::Mesh mesh;
    mesh.name = gmesh.name.empty() ? "mesh" + std::to_string(mesh_index) : gmesh.name;
    if (gmesh.primitives.size() > 1) mesh.name += "/primitive" + std::to_string(prim_index);
    mesh.positions.resize(n);
    for (std::size_t i = 0; i < n; ++i) mesh.positions[i] = glm::vec3(pos.at(i, 0), pos.at(i, 1), pos.at(i, 2));
    if (!flat) {
      const Values& nrm = nrm_it->second;
      if (nrm.ncomp != 3) fail(label + ": NORMAL must be VEC3");
      check_count("NORMAL", nrm);
      mesh.normals.resize(n);
      for (std::size_t i = 0; i < n; ++i) {
        const glm::dvec3 nd(nrm.at(i, 0), nrm.at(i, 1), nrm.at(i, 2));
        const double len = glm::length(nd);
        // Quantised normals (KHR_mesh_quantization, Draco) are only approximately unit length.
        if (!(len > 1e-6)) fail(label + ": NORMAL of vertex " + std::to_string(i) + " has zero length");
        mesh.normals[i] = glm::vec3(nd / len);
      }
    }
    if (auto it = attrs.find("TEXCOORD_0"); it != attrs.end()) {
      if (it->second.ncomp != 2) fail(label + ": TEXCOORD_0 must be VEC2");
      check_count("TEXCOORD_0", it->second);
      mesh.uvs.resize(n);
      for (std::size_t i = 0; i < n; ++i) mesh.uvs[i] = glm::vec2(it->second.at(i, 0), it->second.at(i, 1));
    }
    if (auto it = attrs.find("COLOR_0"); it != attrs.end()) {
      if (it->second.ncomp != 3 && it->second.ncomp != 4) fail(label + ": COLOR_0 must be VEC3 or VEC4");
      check_count("COLOR_0", it->second);
      mesh.colors.resize(n);
      for (std::size_t i = 0; i < n; ++i) {
        mesh.colors[i] = glm::vec3(it->second.at(i, 0), it->second.at(i, 1), it->second.at(i, 2));
      }
    }
    auto j_it = attrs.find("JOINTS_0");
    auto w_it = attrs.find("WEIGHTS_0");
    if ((j_it == attrs.end()) != (w_it == attrs.end())) fail(label + ": JOINTS_0 and WEIGHTS_0 must come together");
    if (j_it != attrs.end()) {
      if (j_it->second.ncomp != 4 || w_it->second.ncomp != 4) fail(label + ": JOINTS_0 and WEIGHTS_0 must be VEC4");
      check_count("JOINTS_0", j_it->second);
      check_count("WEIGHTS_0", w_it->second);
      mesh.joints.resize(n);
      mesh.weights.resize(n);
      for (std::size_t i = 0; i < n; ++i) {
        glm::dvec4 w;
        for (int k = 0; k < 4; ++k) {
          const double j = j_it->second.at(i, k);
          if (j < 0 || j > 65535 || j != std::floor(j)) {
            fail(label + ": JOINTS_0 of vertex " + std::to_string(i) + " is not a valid joint index");
          }
          mesh.joints[i][k] = static_cast<std::uint16_t>(j);
          w[k] = w_it->second.at(i, k);
          if (w[k] < 0) fail(label + ": WEIGHTS_0 of vertex " + std::to_string(i) + " is negative");
        }
        const double sum = w.x + w.y + w.z + w.w;
        if (!(sum > 1e-6)) fail(label + ": WEIGHTS_0 of vertex " + std::to_string(i) + " sum to zero");
        // glTF requires a unit sum; quantised weights only approximate it.
        mesh.weights[i] = glm::vec4(w / sum);
      }
    }

    // Triangles; indices checked against the vertex count. Degenerate triangles (a repeated vertex,
    // or an area scene::validate counts as zero) are dropped, as rasterisers drop them.
    std::vector<std::uint32_t> seq;
    if (!indexed) {
      seq.resize(n);
      for (std::size_t i = 0; i < n; ++i) seq[i] = static_cast<std::uint32_t>(i);
    }
    const std::vector<std::uint32_t>& idx = indexed ? indices : seq;
    for (std::size_t i = 0; i < idx.size(); ++i) {
      if (idx[i] >= n) {
        fail(label + ": index " + std::to_string(i) + " is " + std::to_string(idx[i]) + ", beyond the " +
             std::to_string(n) + " vertices");
      }
    }
    auto add = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
      if (a == b || b == c || a == c) return;
      const glm::vec3 pa = mesh.positions[a], pb = mesh.positions[b], pc = mesh.positions[c];
      const float longest2 = std::max({glm::dot(pb - pa, pb - pa), glm::dot(pc - pb, pc - pb), glm::dot(pa - pc, pa - pc)});
      if (!(glm::length(glm::cross(pb - pa, pc - pa)) > kZeroAreaRelative * longest2)) return;
      if (flat && !(glm::length(face_normal(pa, pb, pc)) > 0.0)) return;
      mesh.triangles.emplace_back(a, b, c);
    };
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      if (idx.size() % 3 != 0) fail(label + ": " + std::to_string(idx.size()) + " indices is not a multiple of 3");
      for (std::size_t t = 0; t + 2 < idx.size(); t += 3) add(idx[t], idx[t + 1], idx[t + 2]);
    } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      for (std::size_t t = 0; t + 2 < idx.size(); ++t) {
        if (t % 2 == 0) {
          add(idx[t], idx[t + 1], idx[t + 2]);
        } else {
          add(idx[t + 1], idx[t], idx[t + 2]);
        }
      }
    } else {
      for (std::size_t t = 1; t + 1 < idx.size(); ++t) add(idx[0], idx[t], idx[t + 1]);
    }
    if (mesh.triangles.empty()) fail(label + ": no non-degenerate triangles");
    if (flat) {
      const std::size_t welded = mesh.positions.size();
      unweld_flat(mesh);
      notice(label + " has no NORMAL: flat normals computed from each triangle's winding, its " +
             std::to_string(welded) + " vertices split into " + std::to_string(mesh.positions.size()) +
             " (3 per triangle)");
    }
    mesh.material = material(prim.material, label);
    const scene::Material& mat = scene.materials[std::size_t(mesh.material)];
    if (mat.albedo_texture >= 0 && mesh.uvs.empty()) {
      std::ostringstream f;
      f << "(" << mat.albedo.x << ", " << mat.albedo.y << ", " << mat.albedo.z << ")";
      notice(label + " has no TEXCOORD_0 but its material " + quoted(mat.name) +
             " has a baseColorTexture: the primitive ignores the texture and shows the base colour factor " + f.str() +
             " (material " + quoted(mat.name + " (untextured)") + ")");
      mesh.material = untextured(mesh.material);
    }
    return mesh;
  }

  void notice(const std::string& what) { scene.notices.push_back(path + ": " + what); }

  // Unnormalised face normal of the counter-clockwise triangle (a, b, c) (glTF: CCW is the front
  // face), in double so that no float overflow or underflow of the cross product can reach it.
  static glm::dvec3 face_normal(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
    const glm::dvec3 da(a);
    return glm::cross(glm::dvec3(b) - da, glm::dvec3(c) - da);
  }

  // Flat shading: every triangle gets its own three vertices carrying the face normal; the other
  // attributes (uv, colour, joints, weights) are copied from the shared vertex. Zero-area triangles
  // never get here (they are dropped, as scene::validate rejects them), so every normal divides by
  // a positive length.
  static void unweld_flat(scene::Mesh& mesh) {
    scene::Mesh out;
    const std::size_t nt = mesh.triangles.size();
    out.positions.reserve(3 * nt);
    out.normals.reserve(3 * nt);
    for (std::size_t t = 0; t < nt; ++t) {
      const glm::uvec3 tri = mesh.triangles[t];
      const glm::dvec3 fn = face_normal(mesh.positions[tri.x], mesh.positions[tri.y], mesh.positions[tri.z]);
      const glm::vec3 unit(fn / glm::length(fn));
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t v = tri[k];
        out.positions.push_back(mesh.positions[v]);
        out.normals.push_back(unit);
        if (!mesh.uvs.empty()) out.uvs.push_back(mesh.uvs[v]);
        if (!mesh.colors.empty()) out.colors.push_back(mesh.colors[v]);
        if (!mesh.joints.empty()) {
          out.joints.push_back(mesh.joints[v]);
          out.weights.push_back(mesh.weights[v]);
        }
      }
      const auto base = static_cast<std::uint32_t>(3 * t);
      out.triangles.emplace_back(base, base + 1, base + 2);
    }
    mesh.positions.swap(out.positions);
    mesh.normals.swap(out.normals);
    mesh.uvs.swap(out.uvs);
    mesh.colors.swap(out.colors);
    mesh.joints.swap(out.joints);
    mesh.weights.swap(out.weights);
    mesh.triangles.swap(out.triangles);
  }

  // The scene material `index` without its albedo texture, for primitives that have no TEXCOORD_0
  // to sample it with (one copy per material, named "NAME (untextured)").
  int untextured(int index) {
    if (auto it = untextured_map.find(index); it != untextured_map.end()) return it->second;
    scene::Material m = scene.materials[std::size_t(index)];
    m.name += " (untextured)";
    m.albedo_texture = -1;
    scene.materials.push_back(m);
    return untextured_map[index] = int(scene.materials.size()) - 1;
  }

  // ---- materials and textures ----

  static float srgb_to_linear(float v) {
    return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
  }

  int texture(int index, const std::string& label) {
    if (auto it = texture_map.find(index); it != texture_map.end()) return it->second;
    if (index < 0 || std::size_t(index) >= model.textures.size()) fail(label + ": texture " + std::to_string(index) + " does not exist");
    const auto& tex = model.textures[std::size_t(index)];
    if (tex.source < 0 || std::size_t(tex.source) >= model.images.size()) {
      fail(label + ": texture " + std::to_string(index) + " has no image source softgi can decode (PNG or JPEG)");
    }
    const auto& img = model.images[std::size_t(tex.source)];
    const std::string ilabel = label + ": image " + std::to_string(tex.source);
    if (img.width <= 0 || img.height <= 0 || img.component < 1 || img.component > 4 ||
        (img.bits != 8 && img.bits != 16)) {
      fail(ilabel + ": undecodable image (" + std::to_string(img.width) + "x" + std::to_string(img.height) + ", " +
           std::to_string(img.component) + " channels, " + std::to_string(img.bits) + " bits)");
    }
    const std::size_t bpc = std::size_t(img.bits / 8);
    const std::size_t npx = std::size_t(img.width) * std::size_t(img.height);
    if (img.image.size() < npx * std::size_t(img.component) * bpc) fail(ilabel + ": pixel data is shorter than its size");
    scene::Texture t;
    t.name = !img.name.empty() ? img.name : !img.uri.empty() ? img.uri : "image" + std::to_string(tex.source);
    t.width = img.width;
    t.height = img.height;
    t.texels.resize(npx);
    const float maxv = img.bits == 8 ? 255.0f : 65535.0f;
    for (std::size_t p = 0; p < npx; ++p) {
      float c[4] = {0, 0, 0, 0};
      for (int k = 0; k < img.component; ++k) {
        const std::size_t off = (p * std::size_t(img.component) + std::size_t(k)) * bpc;
        const float raw = bpc == 1 ? float(img.image[off])
                                   : float(std::uint16_t(img.image[off] | (std::uint16_t(img.image[off + 1]) << 8)));
        c[k] = raw / maxv;
      }
      // Grey (+alpha) images replicate the first channel.
      const glm::vec3 rgb = img.component >= 3 ? glm::vec3(c[0], c[1], c[2]) : glm::vec3(c[0]);
      // Base colour textures are sRGB-encoded (glTF 2.0 spec, section 3.9.2).
      t.texels[p] = glm::vec3(srgb_to_linear(rgb.x), srgb_to_linear(rgb.y), srgb_to_linear(rgb.z));
    }
    scene.textures.push_back(std::move(t));
    const int out = int(scene.textures.size()) - 1;
    texture_map[index] = out;
    return out;
  }

  int material(int index, const std::string& label) {
    if (index < 0) {
      if (default_material < 0) {
        scene::Material m;
        m.name = fs::path(path).filename().string() + ":default";
        // glTF's default material is white (baseColorFactor 1).
        m.albedo = glm::vec3(1.0f);
        scene.materials.push_back(m);
        default_material = int(scene.materials.size()) - 1;
      }
      return default_material;
    }
    if (auto it = material_map.find(index); it != material_map.end()) return it->second;
    if (std::size_t(index) >= model.materials.size()) fail(label + ": material " + std::to_string(index) + " does not exist");
    const auto& gm = model.materials[std::size_t(index)];
    const std::string mlabel = "material " + std::to_string(index) + (gm.name.empty() ? "" : " " + quoted(gm.name));
    scene::Material m;
    m.name = gm.name.empty() ? "material" + std::to_string(index) : gm.name;
    const auto& f = gm.pbrMetallicRoughness.baseColorFactor;
    if (f.size() != 4) fail(mlabel + ": baseColorFactor must have 4 components");
    for (int k = 0; k < 3; ++k) {
      if (!std::isfinite(f[std::size_t(k)]) || f[std::size_t(k)] < 0.0 || f[std::size_t(k)] > 1.0) {
        std::ostringstream s;
        s << mlabel << ": baseColorFactor[" << k << "] is " << f[std::size_t(k)] << ", outside [0, 1]";
        fail(s.str());
      }
      m.albedo[k] = float(f[std::size_t(k)]);
    }
    const auto& bct = gm.pbrMetallicRoughness.baseColorTexture;
    if (bct.index >= 0) {
      if (bct.texCoord != 0) fail(mlabel + ": baseColorTexture uses TEXCOORD_" + std::to_string(bct.texCoord) + "; only TEXCOORD_0 is supported");
      m.albedo_texture = texture(bct.index, mlabel);
    }
    scene.materials.push_back(m);
    const int out = int(scene.materials.size()) - 1;
    material_map[index] = out;
    return out;
  }

  const std::vector<int>& meshes_of(int index, const std::string& label) {
    if (auto it = mesh_map.find(index); it != mesh_map.end()) return it->second;
    if (index < 0 || std::size_t(index) >= model.meshes.size()) fail(label + ": mesh " + std::to_string(index) + " does not exist");
    std::vector<int> out;
    const auto& gm = model.meshes[std::size_t(index)];
    if (gm.primitives.empty()) fail("mesh " + std::to_string(index) + ": no primitives");
    for (std::size_t p = 0; p < gm.primitives.size(); ++p) {
      scene::Mesh mesh = build_primitive(index, int(p));
      scene.meshes.push_back(std::move(mesh));
      out.push_back(int(scene.meshes.size()) - 1);
    }
    return mesh_map[index] = std::move(out);
  }

  // ---- nodes ----

  static std::string number(double v) {
    std::ostringstream s;
    s << v;
    return s.str();
  }

  // Each |scale| in [kMinScale, kMaxScaleAbs]: a node scale of 1e30 is finite as a float yet
  // overflows the world bounds (and the camera framed on them), so it is refused here, at the node.
  // (Translations beyond 1e6 m are finite and reported, with the node, by scene::validate.)
  void check_scale(const std::string& label, const glm::dvec3& s, const char* what) const {
    for (int k = 0; k < 3; ++k) {
      if (!(std::fabs(s[k]) >= kMinScale && std::fabs(s[k]) <= kMaxScaleAbs)) {
        fail(label + ": " + what + "scale[" + std::to_string(k) + "] = " + number(s[k]) + " is outside |scale| in [" +
             number(kMinScale) + ", " + number(kMaxScaleAbs) + "]");
      }
    }
  }

  void set_transform(scene::Node& node, const tinygltf::Node& gn, int index) const {
    const std::string label = node_label(index);
    auto finite = [&](const std::vector<double>& v, const char* what) {
      for (std::size_t i = 0; i < v.size(); ++i) {
        if (!std::isfinite(v[i])) fail(label + ": " + what + "[" + std::to_string(i) + "] is not finite");
      }
    };
    if (!gn.matrix.empty()) {
      if (gn.matrix.size() != 16) fail(label + ": matrix must have 16 elements");
      finite(gn.matrix, "matrix");
      glm::dmat4 m = glm::make_mat4(gn.matrix.data());  // column-major, as glTF stores it
      if (std::fabs(m[0][3]) > 1e-9 || std::fabs(m[1][3]) > 1e-9 || std::fabs(m[2][3]) > 1e-9 ||
          std::fabs(m[3][3] - 1.0) > 1e-9) {
        fail(label + ": matrix is projective (last row must be 0 0 0 1)");
      }
      glm::dvec3 c[3] = {glm::dvec3(m[0]), glm::dvec3(m[1]), glm::dvec3(m[2])};
      glm::dvec3 s(glm::length(c[0]), glm::length(c[1]), glm::length(c[2]));
      check_scale(label, s, "matrix ");
      if (glm::determinant(glm::dmat3(c[0], c[1], c[2])) < 0.0) s.x = -s.x;  // a mirror: fold into x
      const glm::dmat3 r(c[0] / s.x, c[1] / s.y, c[2] / s.z);
      const glm::dmat3 rtr = glm::transpose(r) * r;
      for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) {
          if (std::fabs(rtr[a][b] - (a == b ? 1.0 : 0.0)) > kShearTolerance) {
            fail(label + ": matrix has shear, which cannot be represented as translation, rotation and scale");
          }
        }
      }
      node.translation = glm::vec3(m[3]);
      node.rotation = glm::quat(glm::normalize(glm::quat_cast(r)));
      node.scale = glm::vec3(s);
      return;
    }
    glm::dvec3 t(0.0), sc(1.0);
    if (!gn.translation.empty()) {
      if (gn.translation.size() != 3) fail(label + ": translation must have 3 elements");
      finite(gn.translation, "translation");
      t = glm::dvec3(gn.translation[0], gn.translation[1], gn.translation[2]);
    }
    if (!gn.rotation.empty()) {
      if (gn.rotation.size() != 4) fail(label + ": rotation must have 4 elements");
      finite(gn.rotation, "rotation");
      const glm::dquat q(gn.rotation[3], gn.rotation[0], gn.rotation[1], gn.rotation[2]);  // glTF: x y z w
      const double len = glm::length(q);
      if (!(len > 1e-6)) fail(label + ": rotation quaternion has zero length");
      node.rotation = glm::quat(q / len);
    }
    if (!gn.scale.empty()) {
      if (gn.scale.size() != 3) fail(label + ": scale must have 3 elements");
      finite(gn.scale, "scale");
      sc = glm::dvec3(gn.scale[0], gn.scale[1], gn.scale[2]);
    }
    check_scale(label, sc, "");
    node.translation = glm::vec3(t);
    node.scale = glm::vec3(sc);
  }

  // ---- skins ----

  int skin(int index, const std::string& label) {
    if (auto it = skin_map.find(index); it != skin_map.end()) return it->second;
    if (index < 0 || std::size_t(index) >= model.skins.size()) fail(label + ": skin " + std::to_string(index) + " does not exist");
    const auto& gs = model.skins[std::size_t(index)];
    const std::string slabel = "skin " + std::to_string(index) + (gs.name.empty() ? "" : " " + quoted(gs.name));
    scene::Skin s;
    s.name = gs.name.empty() ? "skin" + std::to_string(index) : gs.name;
    if (gs.joints.empty()) fail(slabel + ": no joints");
    for (int j : gs.joints) {
      if (j < 0 || std::size_t(j) >= model.nodes.size()) fail(slabel + ": joint node " + std::to_string(j) + " does not exist");
      if (node_map[std::size_t(j)] < 0) fail(slabel + ": joint " + node_label(j) + " is not part of the imported scene");
      s.joints.push_back(node_map[std::size_t(j)]);
    }
    s.inverse_bind.assign(gs.joints.size(), glm::mat4(1.0f));
    if (gs.inverseBindMatrices >= 0) {
      const Values ibm = read_accessor(gs.inverseBindMatrices, slabel + " inverseBindMatrices");
      if (ibm.ncomp != 16) fail(slabel + ": inverseBindMatrices must be MAT4");
      if (ibm.count < gs.joints.size()) {
        fail(slabel + ": " + std::to_string(ibm.count) + " inverseBindMatrices for " + std::to_string(gs.joints.size()) + " joints");
      }
      for (std::size_t j = 0; j < gs.joints.size(); ++j) {
        glm::dmat4 m = glm::make_mat4(&ibm.v[j * 16]);
        s.inverse_bind[j] = glm::mat4(m);
      }
    }
    scene.skins.push_back(std::move(s));
    const int out = int(scene.skins.size()) - 1;
    skin_map[index] = out;
    return out;
  }

  // ---- animations ----

  void add_animation(int index, GltfImport& result) {
    const auto& ga = model.animations[std::size_t(index)];
    const std::string alabel = "animation " + std::to_string(index) + (ga.name.empty() ? "" : " " + quoted(ga.name));
    scene::AnimationClip clip;
    clip.name = ga.name.empty() ? "animation" + std::to_string(index) : ga.name;
    clip.loop = true;
    for (std::size_t c = 0; c < ga.channels.size(); ++c) {
      const auto& ch = ga.channels[c];
      const std::string clabel = alabel + " channel " + std::to_string(c);
      scene::AnimationChannel out;
      if (ch.target_path == "translation") {
        out.path = scene::AnimationChannel::Path::Translation;
      } else if (ch.target_path == "rotation") {
        out.path = scene::AnimationChannel::Path::Rotation;
      } else if (ch.target_path == "scale") {
        out.path = scene::AnimationChannel::Path::Scale;
      } else if (ch.target_path == "weights") {
        continue;  // morph targets are not part of the scene model
      } else {
        fail(clabel + ": unknown target path " + quoted(ch.target_path));
      }
      if (ch.target_node < 0 || std::size_t(ch.target_node) >= model.nodes.size()) {
        fail(clabel + ": target node " + std::to_string(ch.target_node) + " does not exist");
      }
      if (node_map[std::size_t(ch.target_node)] < 0) continue;  // animates a node outside the imported scene
      out.node = node_map[std::size_t(ch.target_node)];
      if (ch.sampler < 0 || std::size_t(ch.sampler) >= ga.samplers.size()) {
        fail(clabel + ": sampler " + std::to_string(ch.sampler) + " does not exist");
      }
      const auto& sm = ga.samplers[std::size_t(ch.sampler)];
      bool cubic = false;
      if (sm.interpolation.empty() || sm.interpolation == "LINEAR") {
        out.interp = scene::AnimationChannel::Interp::Linear;
      } else if (sm.interpolation == "STEP") {
        out.interp = scene::AnimationChannel::Interp::Step;
      } else if (sm.interpolation == "CUBICSPLINE") {
        // Only the value keys are kept (tangents dropped), interpolated linearly: see docs/scene_format.md.
        out.interp = scene::AnimationChannel::Interp::Linear;
        cubic = true;
      } else {
        fail(clabel + ": unknown interpolation " + quoted(sm.interpolation));
      }
      const Values in = read_accessor(sm.input, clabel + " input");
      const Values outv = read_accessor(sm.output, clabel + " output");
      if (in.ncomp != 1) fail(clabel + ": input must be SCALAR");
      if (in.count == 0) fail(clabel + ": no keyframes");
      const int want = out.path == scene::AnimationChannel::Path::Rotation ? 4 : 3;
      if (outv.ncomp != want) fail(clabel + ": output must be VEC" + std::to_string(want) + " for " + ch.target_path);
      const std::size_t per_key = cubic ? 3 : 1;
      if (outv.count != in.count * per_key) {
        fail(clabel + ": " + std::to_string(outv.count) + " output values for " + std::to_string(in.count) + " keyframes" +
             (cubic ? " (CUBICSPLINE needs 3 per key)" : ""));
      }
      for (std::size_t k = 0; k < in.count; ++k) {
        const double t = in.v[k];
        if (t < 0) fail(clabel + ": keyframe time " + std::to_string(k) + " is negative");
        if (k > 0 && !(t > in.v[k - 1])) fail(clabel + ": keyframe times are not strictly increasing at key " + std::to_string(k));
        out.times.push_back(float(t));
        const std::size_t src = k * per_key + (cubic ? 1 : 0);
        glm::vec4 v(0.0f);
        for (int c2 = 0; c2 < want; ++c2) v[c2] = float(outv.at(src, c2));
        if (want == 4) {
          const float len = glm::length(v);
          if (!(len > 1e-6f)) fail(clabel + ": rotation key " + std::to_string(k) + " has zero length");
          v /= len;
        }
        out.values.push_back(v);
      }
      clip.duration = std::max(clip.duration, out.times.back());
      clip.channels.push_back(std::move(out));
    }
    if (clip.channels.empty()) return;
    scene.clips.push_back(std::move(clip));
    result.clips.push_back(int(scene.clips.size()) - 1);
  }

  // ---- everything ----

  GltfImport run() {
    load_model();
    GltfImport result;
    const int node_base = int(scene.nodes.size());
    const int mesh_base = int(scene.meshes.size());

    // Roots: the default scene's nodes, else scene 0's, else every node nobody lists as a child.
    std::vector<int> roots;
    const int scene_index = model.defaultScene >= 0 ? model.defaultScene : (model.scenes.empty() ? -1 : 0);
    if (scene_index >= 0) {
      if (std::size_t(scene_index) >= model.scenes.size()) fail("default scene " + std::to_string(scene_index) + " does not exist");
      roots = model.scenes[std::size_t(scene_index)].nodes;
    } else {
      std::vector<bool> child(model.nodes.size(), false);
      for (const auto& n : model.nodes) {
        for (int c : n.children) {
          if (c >= 0 && std::size_t(c) < child.size()) child[std::size_t(c)] = true;
        }
      }
      for (std::size_t i = 0; i < model.nodes.size(); ++i) {
        if (!child[i]) roots.push_back(int(i));
      }
    }
    if (roots.empty()) fail("no nodes to import (the scene is empty)");

    // Depth-first order; a node reached twice means a cycle or a second parent, both invalid glTF.
    node_map.assign(model.nodes.size(), -1);
    std::vector<int> order, parent_of;
    std::vector<std::pair<int, int>> stack;  // (gltf node, scene parent)
    for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.emplace_back(*it, -1);
    while (!stack.empty()) {
      const auto [g, parent] = stack.back();
      stack.pop_back();
      if (g < 0 || std::size_t(g) >= model.nodes.size()) fail("node " + std::to_string(g) + " does not exist");
      if (node_map[std::size_t(g)] >= 0) fail(node_label(g) + " is reached twice (a cycle or two parents)");
      node_map[std::size_t(g)] = node_base + int(order.size());
      order.push_back(g);
      parent_of.push_back(parent);
      const auto& ch = model.nodes[std::size_t(g)].children;
      for (auto c = ch.rbegin(); c != ch.rend(); ++c) stack.emplace_back(*c, node_map[std::size_t(g)]);
    }
    for (std::size_t i = 0; i < order.size(); ++i) {
      const auto& gn = model.nodes[std::size_t(order[i])];
      scene::Node node;
      node.name = gn.name.empty() ? "node" + std::to_string(order[i]) : gn.name;
      node.parent = parent_of[i];
      set_transform(node, gn, order[i]);
      scene.nodes.push_back(node);
    }
    for (int r : roots) result.root_nodes.push_back(node_map[std::size_t(r)]);

    // Meshes, materials and skins, attached to their nodes; primitives after the first become
    // child nodes with identity transforms.
    for (std::size_t i = 0; i < order.size(); ++i) {
      const auto& gn = model.nodes[std::size_t(order[i])];
      const int sn = node_base + int(i);
      int skin_index = -1;
      if (gn.skin >= 0) skin_index = skin(gn.skin, node_label(order[i]));
      if (gn.mesh < 0) {
        if (gn.skin >= 0) fail(node_label(order[i]) + ": has a skin but no mesh");
        continue;
      }
      const std::vector<int> meshes = meshes_of(gn.mesh, node_label(order[i]));
      for (std::size_t p = 0; p < meshes.size(); ++p) {
        const scene::Mesh& m = scene.meshes[std::size_t(meshes[p])];
        if (m.skinned() && skin_index >= 0) {
          const std::size_t nj = scene.skins[std::size_t(skin_index)].joints.size();
          for (std::size_t v = 0; v < m.joints.size(); ++v) {
            for (int k = 0; k < 4; ++k) {
              if (m.weights[v][k] > 0.0f && m.joints[v][k] >= nj) {
                fail(mesh_label(gn.mesh, int(p)) + ": vertex " + std::to_string(v) + " uses joint " +
                     std::to_string(m.joints[v][k]) + " of a skin with " + std::to_string(nj));
              }
            }
          }
        }
        int target = sn;
        if (p > 0) {
          scene::Node child;
          child.name = scene.nodes[std::size_t(sn)].name + "/primitive" + std::to_string(p);
          child.parent = sn;
          scene.nodes.push_back(child);
          target = int(scene.nodes.size()) - 1;
        }
        scene.nodes[std::size_t(target)].mesh = meshes[p];
        scene.nodes[std::size_t(target)].skin = m.skinned() ? skin_index : -1;
      }
    }

    for (std::size_t a = 0; a < model.animations.size(); ++a) add_animation(int(a), result);
    result.meshes_added = int(scene.meshes.size()) - mesh_base;
    return result;
  }
};

}  // namespace

GltfImport load_gltf(const std::string& path, scene::Scene& scene) {
  // The loader only appends (and edits what it appended), so a failure is undone by truncating.
  const std::size_t meshes = scene.meshes.size(), materials = scene.materials.size(), textures = scene.textures.size(),
                    nodes = scene.nodes.size(), skins = scene.skins.size(), clips = scene.clips.size(),
                    notices = scene.notices.size();
  try {
    Loader loader(path, scene);
    return loader.run();
  } catch (...) {
    scene.meshes.resize(meshes);
    scene.materials.resize(materials);
    scene.textures.resize(textures);
    scene.nodes.resize(nodes);
    scene.skins.resize(skins);
    scene.clips.resize(clips);
    scene.notices.resize(notices);
    throw;
  }
}

}  // namespace softgi::io
