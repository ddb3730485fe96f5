// Where a command's files go: checked before the work starts, written so that a failure leaves no
// temporary files and a record that tells the truth about the directory (docs/architecture.md,
// "Writing outputs").
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "softgi/image.hpp"

namespace softgi::app {

// A command's output directory (--out DIR) and its run record (record.json, compare.json, ...).
//
// Before the work: the constructor creates DIR (and its parents) and proves it writable by writing
// and removing a probe file; the record's name must not be taken by a directory. Errors name the
// option and the path, and main() turns them into exit status 1. Directories it created are removed
// again (when still empty) if the command ends without writing a file, so a command that fails on
// a later argument check leaves nothing behind.
//
// Every file goes to NAME.tmp in its own directory and is renamed over NAME; a failed write removes
// its temporary. Names may hold subdirectories ("shexp/final.png"), created as needed.
//
// Policy when a write fails midway: the files already written stay, the failure is collected (file
// and reason) and the remaining writes go on; finish() writes the record last with
// "outputs": {"complete", "written", "missing"}, then throws naming the missing files, so the
// command exits non-zero. Before the first file of a run is written the previous run's record is
// removed: a record in DIR always describes the run that wrote the files next to it, and a
// directory without one (the record itself could not be written, or the command failed after its
// first file) holds the files of an unfinished run.
class OutputDir {
 public:
  using Json = nlohmann::ordered_json;

  // `option` ("--out") names the directory in errors; `record` is the record's file name.
  OutputDir(std::string dir, std::string option, std::string record);
  OutputDir(OutputDir&& other) noexcept;
  OutputDir& operator=(OutputDir&&) = delete;
  OutputDir(const OutputDir&) = delete;
  OutputDir& operator=(const OutputDir&) = delete;
  ~OutputDir();

  const std::string& dir() const { return dir_; }
  // DIR/NAME.
  std::string path(const std::string& name) const;

  // Each writes DIR/NAME and returns true, or collects the failure and returns false.
  bool write_text(const std::string& name, const std::string& text);
  bool write_json(const std::string& name, const Json& j);  // pretty-printed
  bool write_exr(const std::string& name, const Image& img);
  bool write_png(const std::string& name, const Image& img, float exposure = 1.0f);  // tone-mapped
  bool write_png_display(const std::string& name, const Image& img);                 // display-referred
  // NAME.exr and a tone-mapped NAME.png; true when both were written.
  bool write_image_pair(const std::string& name, const Image& img);

  // Names written so far (relative to DIR, in order) and those that could not be, with the reason.
  const std::vector<std::string>& written() const { return written_; }
  struct Missing {
    std::string file, error;
  };
  const std::vector<Missing>& missing() const { return missing_; }

  // Writes the record, with "outputs" added, as the last file; throws std::runtime_error when the
  // record or any earlier file could not be written.
  void finish(Json record);

 private:
  // Runs `write` for DIR/NAME (creating NAME's subdirectories first) and books the result.
  template <class Write>
  bool attempt(const std::string& name, Write&& write);
  void begin_run();

  std::string dir_, option_, record_;
  std::vector<std::string> created_;  // directories the constructor created, outermost first
  std::vector<std::string> written_;
  std::vector<Missing> missing_;
  bool started_ = false;
};

// A command's single output file (-o FILE, --map FILE). The constructor checks, before the work,
// that FILE is not a directory and that its directory exists (it is created otherwise) and is
// writable (probe file); errors name the option and the path. write() goes through FILE.tmp and a
// rename and removes the temporary when it fails; the error names the file. As with OutputDir, a
// directory the constructor created is removed again (when empty) if nothing was written.
class OutputFile {
 public:
  OutputFile(std::string path, std::string option);
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;
  ~OutputFile();

  const std::string& path() const { return path_; }
  // `write(path)` writes the file itself through a temporary and a rename (the io:: writers do);
  // a temporary it leaves behind on failure is removed before the error propagates.
  template <class Write>
  void write(Write&& write) {
    try {
      write(path_);
    } catch (...) {
      remove_temporary();
      throw;
    }
    written_ = true;
  }
  void write_text(const std::string& text);

 private:
  void remove_temporary() const;

  std::string path_, option_;
  std::vector<std::string> created_;
  bool written_ = false;
};

}  // namespace softgi::app
