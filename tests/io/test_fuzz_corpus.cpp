// Replays the fuzzing corpora (grown by scripts/fuzz.sh) through their readers: the scene files of
// tests/fuzz/corpus through io::parse_scene_json, the glTF/GLB files of tests/fuzz/corpus_gltf
// through io::load_gltf and the images of tests/fuzz/corpus_env_image through io::read_rgb_float.
// Every input must either load or throw a std::exception that names it, never crash. Under the
// ASan + UBSan build (scripts/test.sh) this also catches memory errors the fuzzer once found.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "../fuzz/fuzz_inputs.hpp"
#include "softgi/io/gltf.hpp"
#include "softgi/io/image_io.hpp"
#include "softgi/io/scene_file.hpp"
#include "softgi/scene/scene.hpp"
#include "test_support.hpp"

namespace {

// The corpus replays the parser; proxy fits (seconds each) are not what it tests.
softgi::io::LoadOptions no_fits() {
  softgi::io::LoadOptions o;
  o.fit_proxies = false;
  o.cache_dir = "";
  return o;
}

namespace fs = std::filesystem;

const fs::path kFuzz = fs::path(SOFTGI_SOURCE_DIR) / "tests" / "fuzz";
const fs::path kCorpus = kFuzz / "corpus";
const fs::path kGltfCorpus = kFuzz / "corpus_gltf";
const fs::path kImageCorpus = kFuzz / "corpus_env_image";
// The fixtures the fuzzer's relative paths resolve against (quad.gltf, env.exr, ...).
const fs::path kData = kFuzz / "data";

std::vector<fs::path> corpus_files(const fs::path& corpus = kCorpus) {
  std::vector<fs::path> files;
  if (fs::is_directory(corpus)) {
    for (const auto& e : fs::directory_iterator(corpus)) {
      if (e.is_regular_file()) files.push_back(e.path());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(io_fuzz_corpus, EveryCorpusFileParsesOrThrows) {
  const auto files = corpus_files();
  ASSERT_FALSE(files.empty()) << "no corpus in " << kCorpus;
  int accepted = 0, rejected = 0;
  for (const auto& f : files) {
    const std::string name = f.filename().string();
    try {
      softgi::io::parse_scene_json(slurp(f), kData.string(), name, no_fits());
      ++accepted;
    } catch (const std::exception& e) {
      ++rejected;
      // A rejection must say which input it is about.
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << name << ": " << e.what();
    }
  }
  RecordProperty("accepted", accepted);
  RecordProperty("rejected", rejected);
}

// The hand-written seeds say what they expect in their names.
TEST(io_fuzz_corpus, SeedsAreAcceptedOrRejectedAsNamed) {
  int seeds = 0;
  for (const auto& f : corpus_files()) {
    const std::string name = f.filename().string();
    const bool valid = name.rfind("valid_", 0) == 0, invalid = name.rfind("invalid_", 0) == 0;
    if (!valid && !invalid) continue;
    ++seeds;
    std::string error;
    try {
      softgi::io::parse_scene_json(slurp(f), kData.string(), name, no_fits());
    } catch (const std::exception& e) {
      error = e.what();
    }
    if (valid) {
      EXPECT_TRUE(error.empty()) << name << " should load: " << error;
    } else {
      EXPECT_FALSE(error.empty()) << name << " should be rejected";
    }
  }
  EXPECT_GT(seeds, 0);
}

// A corpus input copied to a scratch file named as the fuzz target names it (fuzz_inputs.hpp), so
// it reaches the same reader; returns that path.
std::string as_fuzz_input(const softgi::test::ScratchDir& dir, const fs::path& f, bool gltf) {
  const std::string bytes = slurp(f);
  const auto* data = reinterpret_cast<const std::uint8_t*>(bytes.data());
  const std::string ext = gltf ? softgi::fuzz::gltf_extension(data, bytes.size()) : softgi::fuzz::image_extension(data, bytes.size());
  const std::string path = dir.file(f.filename().string() + ext);
  softgi::test::write_text(path, bytes);
  return path;
}

// Loads one glTF corpus input; returns the error ("" when it loads) and checks what fuzz_gltf.cpp
// checks: a rejection names the file and leaves the scene empty.
std::string replay_gltf(const softgi::test::ScratchDir& dir, const fs::path& f) {
  const std::string path = as_fuzz_input(dir, f, true);
  softgi::scene::Scene s;
  try {
    softgi::io::load_gltf(path, s);
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find(fs::path(path).filename().string()), std::string::npos) << f << ": " << e.what();
    EXPECT_TRUE(s.meshes.empty() && s.nodes.empty() && s.materials.empty() && s.notices.empty()) << f;
    return e.what();
  }
  return "";
}

std::string replay_image(const softgi::test::ScratchDir& dir, const fs::path& f) {
  const std::string path = as_fuzz_input(dir, f, false);
  int w = 0, h = 0;
  std::vector<float> rgb;
  try {
    softgi::io::read_rgb_float(path, w, h, rgb);
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find(fs::path(path).filename().string()), std::string::npos) << f << ": " << e.what();
    return e.what();
  }
  EXPECT_EQ(rgb.size(), std::size_t(w) * std::size_t(h) * 3) << f;
  for (float v : rgb) EXPECT_TRUE(std::isfinite(v)) << f;
  return "";
}

TEST(io_fuzz_corpus, EveryGltfCorpusFileLoadsOrThrows) {
  const auto files = corpus_files(kGltfCorpus);
  ASSERT_FALSE(files.empty()) << "no corpus in " << kGltfCorpus;
  softgi::test::ScratchDir dir;
  int seeds = 0;
  for (const auto& f : files) {
    const std::string name = f.filename().string();
    const std::string error = replay_gltf(dir, f);
    // The hand-made seeds (tests/fuzz/make_seeds.py) say what they expect in their names.
    if (name.rfind("valid_", 0) == 0) {
      ++seeds;
      EXPECT_EQ(error, "") << name << " should load";
    } else if (name.rfind("invalid_", 0) == 0) {
      ++seeds;
      EXPECT_NE(error, "") << name << " should be rejected";
    }
  }
  EXPECT_GT(seeds, 0);
}

TEST(io_fuzz_corpus, EveryImageCorpusFileReadsOrThrows) {
  const auto files = corpus_files(kImageCorpus);
  ASSERT_FALSE(files.empty()) << "no corpus in " << kImageCorpus;
  softgi::test::ScratchDir dir;
  int seeds = 0;
  for (const auto& f : files) {
    const std::string name = f.filename().string();
    const std::string error = replay_image(dir, f);
    if (name.rfind("valid_", 0) == 0) {
      ++seeds;
      EXPECT_EQ(error, "") << name << " should be read";
    } else if (name.rfind("invalid_", 0) == 0) {
      ++seeds;
      EXPECT_NE(error, "") << name << " should be rejected";
    }
  }
  EXPECT_GT(seeds, 0);
}

}  // namespace
