// Environment maps through the scene file: negative components clamped with one notice per map,
// NaN and values above the radiance limit refused with the scene file, field, map file and pixel;
// the HDR maps of the asset set load.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "softgi/io/scene_file.hpp"
#include "softgi/scene/scene.hpp"
#include "softgi/sh/sh.hpp"
#include "test_hdr_files.hpp"
#include "test_support.hpp"

namespace {

using softgi::scene::Scene;
using softgi::test::ScratchDir;
namespace io = softgi::io;
namespace fs = std::filesystem;

using softgi::test::error_of;

Scene load_map(const ScratchDir& dir, const std::string& map) {
  return io::parse_scene_json(R"({"environment": {"map": ")" + map + R"("}})", dir.path().string(), "m.json");
}

#define EXPECT_CONTAINS(haystack, needle) \
  EXPECT_NE((haystack).find(needle), std::string::npos) << "message: " << (haystack) << "\nexpected to contain: " << (needle)

}  // namespace

TEST(io_environment_file, NegativeComponentsAreClampedWithOneNotice) {
  ScratchDir dir;
  std::vector<float> rgb(6 * 3 * 3, 2.0f);
  rgb[3 * (2 * 6 + 4) + 0] = -0.57f;  // pixel (4, 2)
  rgb[3 * (0 * 6 + 1) + 2] = -0.02f;
  softgi::test::write_raw_exr(dir.file("ringing.exr"), 6, 3, rgb);
  const Scene s = load_map(dir, "ringing.exr");
  const auto& e = s.environment;
  ASSERT_EQ(e.map_rgb.size(), rgb.size());
  EXPECT_EQ(e.map_rgb[3 * (2 * 6 + 4) + 0], 0.0f);
  EXPECT_EQ(e.map_rgb[3 * (0 * 6 + 1) + 2], 0.0f);
  EXPECT_EQ(e.map_rgb[1], 2.0f);
  ASSERT_EQ(s.notices.size(), 1u);
  EXPECT_EQ(s.notices[0], "environment map '" + dir.file("ringing.exr") +
                              "': 2 negative pixel components (lowest -0.57 at pixel (4, 2)) clamped to 0");
  softgi::scene::validate(s);  // what the loader leaves is a valid scene
  // A clean map: no notice.
  softgi::test::write_raw_exr(dir.file("clean.exr"), 6, 3, std::vector<float>(6 * 3 * 3, 1.0f));
  EXPECT_TRUE(load_map(dir, "clean.exr").notices.empty());
}

TEST(io_environment_file, NonFiniteAndHugePixelsAreErrors) {
  ScratchDir dir;
  std::vector<float> rgb(4 * 2 * 3, 1.0f);
  rgb[3 * (1 * 4 + 0) + 1] = std::nanf("");
  softgi::test::write_raw_exr(dir.file("nan.exr"), 4, 2, rgb);
  EXPECT_CONTAINS(error_of([&] { load_map(dir, "nan.exr"); }),
                  "m.json: environment.map: " + dir.file("nan.exr") + ": pixel (0, 1) channel 1 is nan");
  rgb[3 * (1 * 4 + 0) + 1] = 3e38f;
  softgi::test::write_raw_exr(dir.file("huge.exr"), 4, 2, rgb);
  EXPECT_CONTAINS(error_of([&] { load_map(dir, "huge.exr"); }),
                  "m.json: environment.map: " + dir.file("huge.exr") + ": pixel (0, 1) channel 1 is 3e+38, above the radiance limit 1e+09");
}

// The Poly Haven maps that scripts/fetch-assets.sh installs are DWAB-compressed and ring slightly
// below zero: they load, clamped, with one notice each naming the map.
TEST(io_environment_file, AssetHdrMapsLoad) {
  const fs::path hdri = fs::path(SOFTGI_SOURCE_DIR) / "assets" / "hdri";
  if (!fs::is_directory(hdri)) GTEST_SKIP() << hdri.string() << " is absent (scripts/fetch-assets.sh installs it)";
  int maps = 0;
  for (const char* name : {"sky.exr", "sunset.exr", "apartment.exr", "studio.exr"}) {
    const fs::path file = hdri / name;
    if (!fs::exists(file)) {
      ADD_FAILURE() << file.string() << " is missing from an asset set that has " << hdri.string();
      continue;
    }
    ++maps;
    Scene s;
    const std::string err = error_of([&] {
      s = io::parse_scene_json(R"({"environment": {"map": ")" + file.string() + R"("}})", ".", "assets.json");
    });
    ASSERT_EQ(err, "(no exception)") << name;
    EXPECT_EQ(s.environment.map_width, 512) << name;
    EXPECT_EQ(s.environment.map_height, 256) << name;
    ASSERT_LE(s.notices.size(), 1u) << name;
    for (const std::string& n : s.notices) {
      EXPECT_CONTAINS(n, "environment map '" + file.string() + "': ");
      EXPECT_CONTAINS(n, "clamped to 0");
      std::cout << "[ notice   ] " << n << "\n";
    }
    for (float v : s.environment.map_rgb) ASSERT_TRUE(std::isfinite(v) && v >= 0.0f) << name;
    const auto L = softgi::scene::environment_sh(s.environment, 4);
    EXPECT_GT(L[0].x + L[0].y + L[0].z, 0.0f) << name;
    if (std::string(name) == "apartment.exr") {
      // Known content (fetch-assets.sh checks the files' hashes): its lowest component, -0.572 at (265, 102).
      ASSERT_EQ(s.notices.size(), 1u) << "apartment.exr has negative pixels";
      EXPECT_CONTAINS(s.notices[0], "(lowest -0.572 at pixel (265, 102)) clamped to 0");
    }
  }
  EXPECT_EQ(maps, 4);
}
