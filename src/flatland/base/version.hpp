// The program's version (CMakeLists.txt's project version) and the git commit it was built from,
// for results' provenance and --version. The commit is read at build time (cmake/version.cmake):
// "unknown" outside a git checkout, with "-dirty" when tracked files had uncommitted changes.
#pragma once

namespace flatland {

const char* program_version();
const char* program_commit();

}  // namespace flatland
