#include "output_dir.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <utility>

#include "softgi/io/image_io.hpp"

namespace softgi::app {

namespace fs = std::filesystem;

namespace {

bool is_regular(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(fs::symlink_status(p, ec));
}

// The io:: writers and write_text_file name their temporary PATH.tmp and remove it on failure; this
// is the fallback for a writer that could not (a regular file only: never a directory in the way).
void remove_temporary_of(const fs::path& p) {
  const fs::path tmp = p.string() + ".tmp";
  std::error_code ec;
  if (is_regular(tmp)) fs::remove(tmp, ec);
}

void write_text_file(const fs::path& path, const std::string& text) {
  const fs::path tmp = path.string() + ".tmp";
  std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
  if (!f) {
    const int err = errno;  // nothing was created: an unopenable temporary is not removed
    throw std::runtime_error(path.string() + ": cannot open " + tmp.string() + " for writing: " + std::strerror(err));
  }
  f << text;
  f.flush();
  f.close();
  std::error_code ec;
  if (!f) {
    fs::remove(tmp, ec);
    throw std::runtime_error(path.string() + ": write failed (" + tmp.string() + ")");
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw std::runtime_error(path.string() + ": cannot rename " + tmp.string() + " into place: " + ec.message());
  }
}

// Creates `dir` and its missing parents; returns those it created, outermost first. Errors name the
// option, the path and, when a file stands where a directory must be, that file.
std::vector<std::string> create_directory(const std::string& dir, const std::string& option) {
  if (dir.empty()) throw std::invalid_argument(option + ": empty path");
  fs::path p = fs::path(dir).lexically_normal();
  if (p.has_parent_path() && p.filename().empty()) p = p.parent_path();  // "out/" -> "out"
  std::vector<std::string> missing;
  std::error_code ec;
  fs::path existing = p;
  while (!existing.empty() && !fs::exists(fs::symlink_status(existing, ec))) {
    missing.insert(missing.begin(), existing.string());
    existing = existing.parent_path();
  }
  const std::string where = option + " '" + dir + "'";
  if (!existing.empty() && !fs::is_directory(existing, ec))
    throw std::runtime_error(where + ": " + (existing == p ? "exists and is not a directory"
                                                           : "cannot create it: '" + existing.string() + "' is not a directory"));
  fs::create_directories(p, ec);
  if (ec) throw std::runtime_error(where + ": cannot create directory: " + ec.message());
  if (!fs::is_directory(p, ec)) throw std::runtime_error(where + ": not a directory");
  return missing;
}

// Proves `dir` writable: creating a file is what every write will do.
void probe_writable(const std::string& dir, const std::string& where) {
  const fs::path probe = fs::path(dir) / (".softgi-write-probe-" + std::to_string(::getpid()));
  std::ofstream f(probe, std::ios::binary | std::ios::trunc);
  const int err = errno;
  const bool ok = f && (f << "probe") && f.flush();
  f.close();
  std::error_code ec;
  if (is_regular(probe)) fs::remove(probe, ec);
  if (!ok) throw std::runtime_error(where + ": directory is not writable: " + std::strerror(err ? err : EACCES));
}

// Removes the directories a check created (innermost first), as long as they are empty.
void remove_created(const std::vector<std::string>& created) {
  for (auto it = created.rbegin(); it != created.rend(); ++it) {
    std::error_code ec;
    if (!fs::is_empty(*it, ec) || ec) return;
    fs::remove(*it, ec);
  }
}

}  // namespace

OutputDir::OutputDir(std::string dir, std::string option, std::string record)
    : dir_(std::move(dir)), option_(std::move(option)), record_(std::move(record)) {
  created_ = create_directory(dir_, option_);
  try {
    const std::string where = option_ + " '" + dir_ + "'";
    probe_writable(dir_, where);
    std::error_code ec;
    const fs::file_status s = fs::symlink_status(fs::path(dir_) / record_, ec);
    if (fs::exists(s) && !fs::is_regular_file(s))
      throw std::runtime_error(where + ": '" + record_ + "' there is not a regular file; the run record cannot be written");
  } catch (...) {
    remove_created(created_);
    throw;
  }
}

OutputDir::OutputDir(OutputDir&& o) noexcept
    : dir_(std::move(o.dir_)),
      option_(std::move(o.option_)),
      record_(std::move(o.record_)),
      created_(std::exchange(o.created_, {})),
      written_(std::exchange(o.written_, {})),
      missing_(std::exchange(o.missing_, {})),
      started_(std::exchange(o.started_, true)) {}

OutputDir::~OutputDir() {
  if (!started_) remove_created(created_);
}

std::string OutputDir::path(const std::string& name) const { return (fs::path(dir_) / name).string(); }

void OutputDir::begin_run() {
  if (started_) return;
  started_ = true;
  // The previous run's record would otherwise describe files this run is about to replace.
  const fs::path old = fs::path(dir_) / record_;
  std::error_code ec;
  if (is_regular(old) && !fs::remove(old, ec))
    throw std::runtime_error(option_ + " '" + dir_ + "': cannot remove the previous run's " + record_ + ": " + ec.message());
}

template <class Write>
bool OutputDir::attempt(const std::string& name, Write&& write) {
  begin_run();
  const fs::path p = fs::path(dir_) / name;
  try {
    const fs::path parent = p.parent_path();
    std::error_code ec;
    if (!parent.empty() && !fs::is_directory(parent, ec)) {
      fs::create_directories(parent, ec);
      if (ec || !fs::is_directory(parent))
        throw std::runtime_error(p.string() + ": cannot create directory '" + parent.string() + "'" + (ec ? ": " + ec.message() : ""));
    }
    write(p.string());
    written_.push_back(name);
    return true;
  } catch (const std::exception& e) {
    remove_temporary_of(p);
    missing_.push_back({name, e.what()});
    std::cerr << "softgi: warning: not written: " << e.what() << "\n";
    return false;
  }
}

bool OutputDir::write_text(const std::string& name, const std::string& text) {
  return attempt(name, [&](const std::string& p) { write_text_file(p, text); });
}

bool OutputDir::write_json(const std::string& name, const Json& j) { return write_text(name, j.dump(2) + "\n"); }

bool OutputDir::write_exr(const std::string& name, const Image& img) {
  return attempt(name, [&](const std::string& p) { io::write_exr(p, img); });
}

bool OutputDir::write_png(const std::string& name, const Image& img, float exposure) {
  return attempt(name, [&](const std::string& p) { io::write_png(p, img, exposure); });
}

bool OutputDir::write_png_display(const std::string& name, const Image& img) {
  return attempt(name, [&](const std::string& p) { io::write_png_display(p, img); });
}

bool OutputDir::write_image_pair(const std::string& name, const Image& img) {
  const bool exr = write_exr(name + ".exr", img);
  const bool png = write_png(name + ".png", img);
  return exr && png;
}

void OutputDir::finish(Json record) {
  begin_run();
  Json missing = Json::array();
  for (const auto& m : missing_) missing.push_back({{"file", m.file}, {"error", m.error}});
  record["outputs"] = {{"complete", missing_.empty()}, {"written", written_}, {"missing", missing}};
  const fs::path p = fs::path(dir_) / record_;
  std::string record_error;
  try {
    write_text_file(p, record.dump(2) + "\n");
  } catch (const std::exception& e) {
    remove_temporary_of(p);
    record_error = e.what();
  }
  if (missing_.empty() && record_error.empty()) return;
  std::string msg = option_ + " '" + dir_ + "': ";
  if (!missing_.empty()) {
    msg += std::to_string(missing_.size()) + " of " + std::to_string(missing_.size() + written_.size()) +
           " output file(s) not written:";
    for (const auto& m : missing_) msg += " [" + m.error + "]";
    msg += record_error.empty() ? "; " + record_ + " lists them under outputs.missing" : "; ";
  }
  if (!record_error.empty()) msg += "no run record: " + record_error;
  throw std::runtime_error(msg);
}

OutputFile::OutputFile(std::string path, std::string option) : path_(std::move(path)), option_(std::move(option)) {
  if (path_.empty()) throw std::invalid_argument(option_ + ": empty path");
  const std::string where = option_ + " '" + path_ + "'";
  std::error_code ec;
  const fs::file_status s = fs::status(path_, ec);
  if (fs::is_directory(s)) throw std::runtime_error(where + ": is a directory");
  if (fs::exists(s) && !fs::is_regular_file(s)) throw std::runtime_error(where + ": exists and is not a regular file");
  if (fs::path(path_).filename().empty()) throw std::invalid_argument(where + ": names a directory, not a file");
  const fs::path parent = fs::path(path_).parent_path();
  if (!parent.empty()) created_ = create_directory(parent.string(), where + ": directory");
  try {
    probe_writable(parent.empty() ? "." : parent.string(), where);
  } catch (...) {
    remove_created(created_);
    throw;
  }
}

OutputFile::~OutputFile() {
  if (!written_) remove_created(created_);
}

void OutputFile::remove_temporary() const { remove_temporary_of(path_); }

void OutputFile::write_text(const std::string& text) {
  write([&](const std::string& p) { write_text_file(p, text); });
}

}  // namespace softgi::app
