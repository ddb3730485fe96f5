// The reference cache: the scene content hash sees every change that alters a render and ignores
// names; entries round-trip bit-exactly; an entry without its meta.json (an interrupted write) is
// no entry, a damaged one is reported and not served; SOFTGI_CACHE_DIR=off caches nothing.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

#include "softgi/io/reference_cache.hpp"
#include "softgi/scene/builtin.hpp"

using namespace softgi;
namespace fs = std::filesystem;

namespace {

// Points SOFTGI_CACHE_DIR at a fresh folder for one test and restores it after.
class CacheDir {
 public:
  explicit CacheDir(const std::string& value) {
    if (const char* v = std::getenv("SOFTGI_CACHE_DIR")) old_ = v, had_ = true;
    dir_ = (fs::temp_directory_path() / ("softgi_refcache_" + std::to_string(::getpid()))).string();
    fs::remove_all(dir_);
    setenv("SOFTGI_CACHE_DIR", value.empty() ? dir_.c_str() : value.c_str(), 1);
  }
  ~CacheDir() {
    fs::remove_all(dir_);
    if (had_) setenv("SOFTGI_CACHE_DIR", old_.c_str(), 1);
    else unsetenv("SOFTGI_CACHE_DIR");
  }

 private:
  std::string dir_, old_;
  bool had_ = false;
};

io::CachedReference sample_reference() {
  io::CachedReference r;
  r.direct = Image(5, 3);
  r.indirect = Image(5, 3);
  r.final_image = Image(5, 3);
  for (std::size_t i = 0; i < r.direct.rgb.size(); ++i) {
    r.direct.rgb[i] = glm::vec3(0.1f * i, 1.0f / (i + 3.0f), 3.14159f);
    r.indirect.rgb[i] = glm::vec3(1e-7f * i, 12345.678f, 0.0f);
    r.final_image.rgb[i] = r.direct.rgb[i] + r.indirect.rgb[i];
  }
  r.seconds = 1.25;
  r.rays = 123456789012ll;
  r.spp = 64;
  return r;
}

}  // namespace

TEST(ReferenceCache, SceneHashSeesContentAndIgnoresNames) {
  const scene::Scene a = scene::make_builtin("spheres");
  const std::uint64_t h = io::scene_content_hash(a);
  EXPECT_EQ(io::scene_content_hash(scene::make_builtin("spheres")), h);
  scene::Scene renamed = a;
  renamed.name = "other";
  renamed.source = "elsewhere";
  renamed.nodes[0].name = "x";
  EXPECT_EQ(io::scene_content_hash(renamed), h);
  auto changed = [&](auto edit) {
    scene::Scene b = a;
    edit(b);
    return io::scene_content_hash(b) != h;
  };
  EXPECT_TRUE(changed([](scene::Scene& b) { b.meshes[0].positions[0].x += 1e-6f; }));
  EXPECT_TRUE(changed([](scene::Scene& b) { b.materials[0].albedo.g *= 0.5f; }));
  EXPECT_TRUE(changed([](scene::Scene& b) { b.nodes[0].translation.y += 0.1f; }));
  EXPECT_TRUE(changed([](scene::Scene& b) { b.camera.fov_y_deg += 1.0f; }));
  EXPECT_TRUE(changed([](scene::Scene& b) { b.environment.sun_radiance *= 2.0f; }));
  EXPECT_TRUE(changed([](scene::Scene& b) { b.environment.map_rgb.push_back(1.0f); }));
  EXPECT_TRUE(changed([](scene::Scene& b) { b.lights.push_back({}); }));
  EXPECT_TRUE(changed([](scene::Scene& b) { b.proxies[0].spheres[0].radius *= 1.01f; }));
  EXPECT_TRUE(changed([](scene::Scene& b) { b.active_clip = b.active_clip + 1; }));
  EXPECT_NE(io::reference_cache_key(h, "spp 64"), io::reference_cache_key(h, "spp 65"));
  EXPECT_EQ(io::reference_cache_key(h, "spp 64"), io::reference_cache_key(h, "spp 64"));
}

TEST(ReferenceCache, EntriesRoundTripAndDamagedOnesAreNotServed) {
  CacheDir cache("");
  const std::string key = io::reference_cache_key(42, "test");
  std::string why;
  EXPECT_FALSE(io::read_cached_reference(key, why));
  EXPECT_TRUE(why.empty()) << why;
  const io::CachedReference r = sample_reference();
  io::write_cached_reference(key, r, "a test entry");
  const auto back = io::read_cached_reference(key, why);
  ASSERT_TRUE(back) << why;
  EXPECT_EQ(back->final_image.rgb, r.final_image.rgb);
  EXPECT_EQ(back->direct.rgb, r.direct.rgb);
  EXPECT_EQ(back->indirect.rgb, r.indirect.rgb);
  EXPECT_EQ(back->seconds, r.seconds);
  EXPECT_EQ(back->rays, r.rays);
  EXPECT_EQ(back->spp, r.spp);
  const fs::path dir = io::reference_cache_entry(key);
  // Damaged image: reported, not served.
  { std::ofstream(dir / "final.exr", std::ios::trunc) << "not an exr"; }
  EXPECT_FALSE(io::read_cached_reference(key, why));
  EXPECT_NE(why.find(dir.string()), std::string::npos) << why;
  // Written again it is whole again; without meta.json (an interrupted write) there is no entry.
  io::write_cached_reference(key, r, "a test entry");
  ASSERT_TRUE(io::read_cached_reference(key, why)) << why;
  fs::remove(dir / "meta.json");
  EXPECT_FALSE(io::read_cached_reference(key, why));
  EXPECT_TRUE(why.empty()) << why;
}

TEST(ReferenceCache, OffCachesNothing) {
  CacheDir cache("off");
  const std::string key = io::reference_cache_key(7, "off");
  EXPECT_EQ(io::reference_cache_entry(key), "");
  io::write_cached_reference(key, sample_reference(), "ignored");
  std::string why;
  EXPECT_FALSE(io::read_cached_reference(key, why));
}
