// The build's code generators (gen/sh_plan_cpp.cpp, shaders/gen/sh_plan_glsl.cpp) write their output
// through this: unchanged content leaves the file alone (so that what includes it is not rebuilt),
// and new content is written beside and renamed, so that an interrupted build never leaves half a
// file. Returns 0, or 1 after printing what failed, prefixed with `tool`.
#ifndef SOFTGI_GEN_WRITE_GENERATED_HPP
#define SOFTGI_GEN_WRITE_GENERATED_HPP

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

namespace softgi::gen {

inline int write_generated(const char* tool, const char* out_path, const std::string& text) {
  std::ifstream old(out_path, std::ios::binary);
  if (old) {
    std::ostringstream have;
    have << old.rdbuf();
    if (have.str() == text) return 0;
  }
  const std::string tmp = std::string(out_path) + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << text;
    if (!out.flush()) {
      std::fprintf(stderr, "%s: cannot write %s\n", tool, tmp.c_str());
      return 1;
    }
  }
  if (std::rename(tmp.c_str(), out_path) != 0) {
    std::fprintf(stderr, "%s: cannot rename %s to %s\n", tool, tmp.c_str(), out_path);
    return 1;
  }
  return 0;
}

}  // namespace softgi::gen

#endif
