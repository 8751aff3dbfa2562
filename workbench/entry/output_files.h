// The files the entry points write into the user's output folder: the folder checked before any
// work starts (an input error naming it), and every file written under a temporary name, then
// renamed, so that an interrupted run never leaves a half-written file under the final name.
#pragma once

#include <string>

namespace parafab::entry {

/// Creates `dir` (and its parents) if needed and checks that a file can be created in it;
/// otherwise throws parafab::Error "output folder DIR cannot be written: REASON".
void require_writable_folder(const std::string& dir);

/// A file written under DIR/.NAME.partial-PID and renamed to DIR/NAME by commit(); removed if
/// never committed (an exception or an interruption on the way).
class AtomicFile {
 public:
  explicit AtomicFile(std::string path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  /// Where to write now.
  const std::string& temporary() const { return temporary_; }
  /// Renames the temporary file to the final path (replacing an older file there).
  void commit();

 private:
  std::string path_, temporary_;
  bool committed_ = false;
};

/// `text` into `path` through an AtomicFile.
void write_text_atomically(const std::string& path, const std::string& text);

}  // namespace parafab::entry
