// Run-time lookup of the installed data folders (see install_paths.h).
#include "install_paths.h"

#include <dlfcn.h>
#include <link.h>

#include <cstdlib>
#include <filesystem>
#include <system_error>

#ifndef PARAFAB_VERSION
#error "PARAFAB_VERSION must be defined (workbench/entry/CMakeLists.txt)"
#endif
#ifndef PARAFAB_SCRIPTS_SOURCE_DIR
#define PARAFAB_SCRIPTS_SOURCE_DIR ""
#endif
#ifndef PARAFAB_SCRIPTS_FROM_BIN
#define PARAFAB_SCRIPTS_FROM_BIN "../share/parafab/scripts"
#endif
#ifndef PARAFAB_SCRIPTS_FROM_PYTHON
#define PARAFAB_SCRIPTS_FROM_PYTHON "../../../share/parafab/scripts"
#endif

namespace parafab::entry {

namespace fs = std::filesystem;

namespace {

// The file of the object this code is linked into: the Python module (a shared object, named
// by its link map) or the executable (the main program's link map has an empty name; its
// file is /proc/self/exe, symlinks resolved, so a link to the CLI finds the real install).
fs::path this_binary() {
  Dl_info info{};
  link_map* map = nullptr;
  if (dladdr1(reinterpret_cast<void*>(&this_binary), &info, reinterpret_cast<void**>(&map), RTLD_DL_LINKMAP) &&
      map && map->l_name && map->l_name[0]) {
    std::error_code ec;
    const fs::path p = fs::weakly_canonical(map->l_name, ec);
    return ec ? fs::path(map->l_name) : p;
  }
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path() : exe;
}

}  // namespace

const char* version() { return PARAFAB_VERSION; }

std::string scripts_dir() {
  if (const char* env = std::getenv("PARAFAB_SCRIPTS_DIR"); env && *env) return env;
  const fs::path binary = this_binary();
  if (!binary.empty()) {
    for (const char* relative : {PARAFAB_SCRIPTS_FROM_BIN, PARAFAB_SCRIPTS_FROM_PYTHON}) {
      const fs::path dir = (binary.parent_path() / relative).lexically_normal();
      std::error_code ec;
      if (fs::is_regular_file(dir / "plot_optimization.py", ec)) return dir.string();
    }
  }
  return PARAFAB_SCRIPTS_SOURCE_DIR;
}

}  // namespace parafab::entry
