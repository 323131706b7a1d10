// The files a command reads and writes, whatever a user names: regular files, pipes, devices,
// symbolic links, the standard output. Inputs are read with a size limit, and a wait on a pipe
// stays cancellable. Outputs are examined before any work; regular files are written all or
// nothing (a temporary file renamed into place), and everything else (a device, a pipe, the
// standard output) is written through, so that a device node or a file the user did not name
// is never replaced. docs/limits.md describes the rules for users.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "flatland/base/status.hpp"

namespace flatland {

// The largest input read: 1 GiB. A scene of a million curves is about 85 MB, and check_result_size
// keeps the samples of every result the program writes below this.
inline constexpr std::uint64_t kMaxInputBytes = std::uint64_t{1} << 30;

// The message of the error that a read or write ended by its cancel flag returns.
inline constexpr const char* kFileWaitCancelled = "cancelled while waiting for a pipe or device";

// What an input is expected to hold, for stopping early on a stream that cannot be it.
enum class InputContent { JsonObject, Text };

// Reads the whole of `path`; `what` names it in errors ("scene file", "result file"). A regular
// file larger than `limit` is refused before it is read. A pipe or device is read in pieces and
// refused once past `limit`; for InputContent::JsonObject its reading stops as soon as its first
// character (after white space and a byte-order mark) is not '{', since no JSON object follows,
// and the parser then reports that character as any file's. Opening and reading never wait
// without watching `cancel`: a pipe with no writer yet, or one that is slow to write, is polled
// every 50 ms, and a set flag ends the read with kFileWaitCancelled.
Result<std::string> read_input_file(const std::string& path, const std::string& what,
                                    const std::atomic<bool>* cancel = nullptr,
                                    InputContent content = InputContent::JsonObject,
                                    std::uint64_t limit = kMaxInputBytes);

// Which file a path names, to tell when two paths name the same file whatever their spelling: an
// existing file's device and inode, or for a file not yet made, its directory's and its name.
struct FileIdentity {
  dev_t device = 0;
  ino_t inode = 0;
  std::string name;  // empty for an existing file
  bool operator==(const FileIdentity&) const = default;
};
// The identity of an existing file (following symbolic links), or nullopt.
std::optional<FileIdentity> existing_file_identity(const std::string& path);

// How an output is written, decided by what its path names.
enum class OutputKind {
  NewFile,         // nothing there yet: written beside it under a temporary name, then renamed
  ReplacedFile,    // a regular file (perhaps through symbolic links): replaced by a rename in its
                   // own directory, so a link stays a link
  WrittenThrough,  // a character device (/dev/null, a terminal) or a FIFO: opened and written
  StandardStream,  // "-" (the standard output), or a path naming what descriptor 1 or 2 is when
                   // that is a regular file or a pipe: written to that descriptor where it stands
};

struct OutputTarget {
  std::string path;  // as the user gave it
  OutputKind kind = OutputKind::NewFile;
  std::string real_path;  // the file renamed over or opened (symbolic links resolved)
  FileIdentity identity;  // of the file that will hold the output
  int descriptor = -1;    // StandardStream: 1 or 2
  // Whether this output is where the standard output goes, so that a command's reports must go
  // elsewhere (to standard error) to keep out of it: true for a StandardStream on descriptor 1, and for a terminal
  // or pipe that descriptor 1 is also connected to.
  bool shares_standard_output = false;
  // Whether it is the null device, which takes any number of outputs at once.
  bool discards = false;
};

// Examines `path` as an output before any work starts: "-" is the standard output; a name in an
// existing directory that can be written, a regular file that can be replaced (not another user's
// in a sticky directory such as /tmp), a character device or FIFO that can be opened for writing.
// Directories, block devices, sockets, and symbolic links to nothing are refused. The error names
// the path and the fix.
Result<OutputTarget> examine_output(const std::string& path);
// examine_output without the target, for callers that only check.
Status check_output_file(const std::string& path);

// Output files written all or nothing where the file system allows it. stage() writes a file's
// contents to a temporary file in its directory (.NAME.tmpPID-RANDOM, so the rename is atomic),
// synced to the disk, or keeps them for an output that is written through; commit() renames the
// temporary files over their targets and writes the others, in staging order. A rename replaces
// this name only: other hard links to the file keep the old contents. Files staged but not
// committed (an error, an interrupt) are removed when the object goes away, so no partial regular
// file is ever left. A temporary file that a killed process (SIGKILL, power loss) left behind is
// removed by the next stage() of the same target once its process no longer runs. A
// write-through output that waits (a FIFO with no reader, a full pipe) watches `cancel` every 50 ms.
class OutputFiles {
 public:
  explicit OutputFiles(const std::atomic<bool>* cancel = nullptr) : cancel_(cancel) {}
  OutputFiles(const OutputFiles&) = delete;
  OutputFiles& operator=(const OutputFiles&) = delete;
  ~OutputFiles();

  Status stage(const std::string& path, std::string contents);
  // Renames or writes every staged file, in staging order.
  Status commit();
  // Removes every staged file that is not committed yet.
  void discard();

 private:
  struct Staged {
    OutputTarget target;
    std::string temporary;  // for NewFile and ReplacedFile
    std::string contents;   // for WrittenThrough and StandardStream
  };
  std::vector<Staged> staged_;
  const std::atomic<bool>* cancel_ = nullptr;
};

// Writes `contents` to `path` as OutputFiles does (all or nothing for a regular file). The error
// names the path and the reason.
Status write_file_atomically(const std::string& path, const std::string& contents,
                             const std::atomic<bool>* cancel = nullptr);

}  // namespace flatland
