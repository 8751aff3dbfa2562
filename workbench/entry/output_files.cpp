#include "output_files.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "common/error.h"

namespace parafab::entry {

namespace fs = std::filesystem;

void require_writable_folder(const std::string& dir) {
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    PARAFAB_INPUT_ERROR("output folder " << dir << " cannot be written: it is a file, not a folder");
  fs::create_directories(dir, ec);
  if (ec) PARAFAB_INPUT_ERROR("output folder " << dir << " cannot be written: " << ec.message());
  const std::string probe = dir + "/.parafab-write-check-" + std::to_string(::getpid());
  {
    std::ofstream f(probe);
    if (!f || !(f << "x")) {
      const std::string reason = std::strerror(errno);
      fs::remove(probe, ec);
      PARAFAB_INPUT_ERROR("output folder " << dir << " cannot be written: " << reason);
    }
  }
  fs::remove(probe, ec);
}

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)) {
  const fs::path p(path_);
  temporary_ = (p.parent_path() / ("." + p.filename().string() + ".partial-" + std::to_string(::getpid()))).string();
}

AtomicFile::~AtomicFile() {
  if (committed_) return;
  std::error_code ec;
  fs::remove(temporary_, ec);
}

void AtomicFile::commit() {
  std::error_code ec;
  fs::rename(temporary_, path_, ec);
  PARAFAB_VERIFY(!ec, "cannot write " << path_ << ": " << ec.message());
  committed_ = true;
}

FolderLock::FolderLock(const std::string& dir) : path_(dir + "/.parafab.lock") {
  fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) PARAFAB_INPUT_ERROR("output folder " << dir << " cannot be written: " << std::strerror(errno));
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd_);
    fd_ = -1;
    PARAFAB_INPUT_ERROR("output folder " << dir << " is being written by another parafab run (" << path_
                                         << " is locked): choose another folder, or wait for that run to end");
  }
}

FolderLock::~FolderLock() {
  if (fd_ < 0) return;
  ::unlink(path_.c_str());  // before the lock goes: a run waiting on it finds no stale file
  ::close(fd_);
}

void refuse_output_over_input(const std::string& output, const std::string& input) {
  std::error_code ea, eb;
  if (output.empty() || input.empty() || !fs::exists(input, ea)) return;
  if (fs::exists(output, eb) ? fs::equivalent(output, input, ea)
                             : fs::weakly_canonical(output, ea) == fs::weakly_canonical(input, eb))
    PARAFAB_INPUT_ERROR("the output " << output << " would overwrite the input " << input
                                      << ": write it elsewhere (another -o)");
}

void write_text_atomically(const std::string& path, const std::string& text) {
  AtomicFile file(path);
  {
    std::ofstream f(file.temporary());
    PARAFAB_VERIFY(f && (f << text) && f.flush(), "cannot write " << path);
  }
  file.commit();
}

}  // namespace parafab::entry
