// Replays the scene-file fuzzing corpus (tests/fuzz/corpus, grown by scripts/fuzz.sh) through
// io::parse_scene_json: every input must either load or throw a std::exception, never crash. Under
// the ASan + UBSan build (scripts/test.sh) this also catches memory errors the fuzzer once found.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/io/scene_file.hpp"

namespace {

namespace fs = std::filesystem;

const fs::path kCorpus = fs::path(SOFTGI_SOURCE_DIR) / "tests" / "fuzz" / "corpus";
// The fixtures the fuzzer's relative paths resolve against (quad.gltf, env.exr, ...).
const fs::path kData = fs::path(SOFTGI_SOURCE_DIR) / "tests" / "fuzz" / "data";

std::vector<fs::path> corpus_files() {
  std::vector<fs::path> files;
  if (fs::is_directory(kCorpus)) {
    for (const auto& e : fs::directory_iterator(kCorpus)) {
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
      softgi::io::parse_scene_json(slurp(f), kData.string(), name);
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
      softgi::io::parse_scene_json(slurp(f), kData.string(), name);
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

}  // namespace
