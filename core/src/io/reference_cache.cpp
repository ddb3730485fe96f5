// The reference cache (softgi/io/reference_cache.hpp).
#include "softgi/io/reference_cache.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "fnv.hpp"
#include "softgi/io/image_io.hpp"
#include "softgi/io/proxy_fit.hpp"

namespace softgi::io {

namespace fs = std::filesystem;

std::uint64_t scene_content_hash(const scene::Scene& s) {
  Fnv f;
  f.pod(s.meshes.size());
  for (const auto& m : s.meshes) {
    f.vec(m.positions);
    f.vec(m.normals);
    f.vec(m.uvs);
    f.vec(m.colors);
    f.vec(m.triangles);
    f.pod(m.material);
    f.vec(m.joints);
    f.vec(m.weights);
  }
  f.pod(s.materials.size());
  for (const auto& m : s.materials) {
    f.pod(m.albedo);
    f.pod(m.albedo_texture);
    f.pod(m.phong_ns);
    f.pod(m.glossy);
  }
  f.pod(s.textures.size());
  for (const auto& t : s.textures) {
    f.pod(t.width);
    f.pod(t.height);
    f.vec(t.texels);
  }
  f.pod(s.nodes.size());
  for (const auto& n : s.nodes) {
    f.pod(n.parent);
    f.pod(n.translation);
    f.pod(n.rotation);
    f.pod(n.scale);
    f.pod(n.mesh);
    f.pod(n.skin);
  }
  f.pod(s.skins.size());
  for (const auto& k : s.skins) {
    f.vec(k.joints);
    f.vec(k.inverse_bind);
  }
  f.pod(s.clips.size());
  for (const auto& c : s.clips) {
    f.pod(c.duration);
    f.pod(c.loop);
    f.pod(c.channels.size());
    for (const auto& ch : c.channels) {
      f.pod(ch.node);
      f.pod(ch.path);
      f.pod(ch.interp);
      f.vec(ch.times);
      f.vec(ch.values);
    }
  }
  f.pod(s.active_clip);
  f.pod(s.proxies.size());
  for (const auto& p : s.proxies) {
    f.pod(p.node);
    f.pod(p.spheres.size());
    for (const auto& sp : p.spheres) {
      f.pod(sp.center);
      f.pod(sp.radius);
    }
    f.vec(p.joints);
    f.vec(p.weights);
    f.pod(p.albedo);
    f.vec(p.sphere_albedo);
  }
  const scene::Camera& c = s.camera;
  f.pod(c.position);
  f.pod(c.target);
  f.pod(c.up);
  f.pod(c.fov_y_deg);
  f.pod(c.width);
  f.pod(c.height);
  const scene::Environment& e = s.environment;
  f.pod(e.kind);
  f.pod(e.zenith);
  f.pod(e.horizon);
  f.pod(e.ground);
  f.pod(e.sun_direction);
  f.pod(e.sun_radius);
  f.pod(e.sun_radiance);
  f.pod(e.map_width);
  f.pod(e.map_height);
  f.vec(e.map_rgb);
  f.pod(e.intensity);
  f.pod(e.rotation_y);
  f.pod(s.lights.size());
  for (const auto& l : s.lights) {
    f.pod(l.position);
    f.pod(l.radius);
    f.pod(l.radiance);
    f.pod(l.node);
  }
  return f.h;
}

std::string reference_cache_key(std::uint64_t scene_hash, const std::string& settings) {
  Fnv f;
  f.str(settings);
  char buf[40];
  std::snprintf(buf, sizeof buf, "%016llx-%016llx", static_cast<unsigned long long>(scene_hash), static_cast<unsigned long long>(f.h));
  return buf;
}

std::string reference_cache_entry(const std::string& key) {
  const std::string dir = proxy_cache_dir();
  if (dir.empty()) return "";
  return (fs::path(dir) / "references" / key).string();
}

std::optional<CachedReference> read_cached_reference(const std::string& key, std::string& why) {
  why.clear();
  const std::string dir = reference_cache_entry(key);
  if (dir.empty() || !fs::exists(fs::path(dir) / "meta.json")) return std::nullopt;
  try {
    std::ifstream in(fs::path(dir) / "meta.json");
    const nlohmann::json j = nlohmann::json::parse(in);
    CachedReference r;
    r.seconds = j.at("seconds").get<double>();
    r.rays = j.at("rays").get<long long>();
    r.spp = j.at("spp").get<int>();
    r.direct = read_image((fs::path(dir) / "direct.exr").string());
    r.indirect = read_image((fs::path(dir) / "indirect.exr").string());
    r.final_image = read_image((fs::path(dir) / "final.exr").string());
    const int w = j.at("width").get<int>(), h = j.at("height").get<int>();
    for (const Image* img : {&r.direct, &r.indirect, &r.final_image})
      if (img->width != w || img->height != h) throw std::runtime_error("an image is not the recorded " + std::to_string(w) + "x" + std::to_string(h));
    return r;
  } catch (const std::exception& ex) {
    why = "reference cache entry " + dir + " is unreadable (" + ex.what() + ")";
    return std::nullopt;
  }
}

void write_cached_reference(const std::string& key, const CachedReference& r, const std::string& description) {
  const std::string dir = reference_cache_entry(key);
  if (dir.empty()) return;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error("reference cache: cannot create " + dir + ": " + ec.message());
  // meta.json, written last and renamed into place, marks the entry complete.
  fs::remove(fs::path(dir) / "meta.json", ec);
  write_exr((fs::path(dir) / "direct.exr").string(), r.direct);
  write_exr((fs::path(dir) / "indirect.exr").string(), r.indirect);
  write_exr((fs::path(dir) / "final.exr").string(), r.final_image);
  nlohmann::json j;
  j["description"] = description;
  j["seconds"] = r.seconds;
  j["rays"] = r.rays;
  j["spp"] = r.spp;
  j["width"] = r.final_image.width;
  j["height"] = r.final_image.height;
  const fs::path tmp = fs::path(dir) / "meta.json.tmp";
  {
    std::ofstream out(tmp);
    out << j.dump(1) << "\n";
    if (!out) throw std::runtime_error("reference cache: cannot write " + tmp.string());
  }
  fs::rename(tmp, fs::path(dir) / "meta.json", ec);
  if (ec) throw std::runtime_error("reference cache: cannot finish " + dir + ": " + ec.message());
}

}  // namespace softgi::io
