#include "output_files.h"

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

void write_text_atomically(const std::string& path, const std::string& text) {
  AtomicFile file(path);
  {
    std::ofstream f(file.temporary());
    PARAFAB_VERIFY(f && (f << text) && f.flush(), "cannot write " << path);
  }
  file.commit();
}

}  // namespace parafab::entry
