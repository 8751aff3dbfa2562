#include "part_preflight.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "common/error.h"
#include "part_reader.h"

namespace parafab::entry {

void preflight_part_read(const std::string& path) {
  if (!std::filesystem::is_regular_file(path)) return;  // the real reading names the problem
  const pid_t child = ::fork();
  if (child < 0) return;  // no child: read in-process as before
  if (child == 0) {
    try {
      occ::ReadOptions options;
      options.surfaces_allowed = true;  // the translation is what is tried; the solid checks come later
      occ::read_part(path, options);
    } catch (...) {
    }
    ::_exit(0);
  }
  int status = 0;
  while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFSIGNALED(status))
    PARAFAB_INPUT_ERROR("part file " << path << " crashes OpenCASCADE's reader (" << ::strsignal(WTERMSIG(status))
                                     << "): the file is corrupt; export it again from the CAD system");
}

}  // namespace parafab::entry
