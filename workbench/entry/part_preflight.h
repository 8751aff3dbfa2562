// A first reading of a part file in a forked child process, for the CLI: OpenCASCADE 7.6's STEP
// translator crashes (SIGSEGV) on some corrupt files that pass its own load checks (an entity
// referenced where another type is expected: tests/fuzz/fuzz_inputs.cpp found them), and a crash
// in the child becomes an input error naming the file instead of killing the command.
#pragma once

#include <string>

namespace parafab::entry {

/// Reads `path` (STEP or BREP) once in a child process. Throws parafab::Error when the child
/// dies on a signal; any other outcome (the part, or an input error the real reading will
/// report) returns. Forks: call it only before the caller has started threads (the CLI does,
/// before its work); the Python module and FreeCAD read in-process.
void preflight_part_read(const std::string& path);

}  // namespace parafab::entry
