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

/// An exclusive lock on an output folder for the length of a run (flock on DIR/.parafab.lock): a
/// second run into the same folder, in this process or another, is refused at once with an input
/// error naming the folder, so two runs never mix their files. Released (and the lock file
/// removed) by the destructor, or by the system if the process dies.
class FolderLock {
 public:
  explicit FolderLock(const std::string& dir);
  ~FolderLock();
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;

 private:
  std::string path_;
  int fd_ = -1;
};

/// Refuses (input error) an output that is one of the run's inputs: "the output OUT would
/// overwrite the input IN". Paths that do not exist yet cannot be inputs.
void refuse_output_over_input(const std::string& output, const std::string& input);

/// `text` into `path` through an AtomicFile.
void write_text_atomically(const std::string& path, const std::string& text);

}  // namespace parafab::entry
