#include "flatland/base/files.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <random>
#include <system_error>

#include "flatland/base/resources.hpp"

namespace flatland {

namespace {

namespace fs = std::filesystem;

// How long a wait on a pipe or device lasts before the cancel flag is looked at again.
constexpr int kWaitMilliseconds = 50;

bool is_set(const std::atomic<bool>* flag) { return flag != nullptr && flag->load(std::memory_order_relaxed); }

std::string reason(int error) { return std::strerror(error); }

// A file descriptor closed when it goes out of scope.
class Descriptor {
 public:
  explicit Descriptor(int fd = -1) : fd_(fd) {}
  ~Descriptor() {
    if (fd_ >= 0) ::close(fd_);
  }
  Descriptor(const Descriptor&) = delete;
  Descriptor& operator=(const Descriptor&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

// Waits at most kWaitMilliseconds for `events` on `fd`: >0 ready, 0 not yet, <0 an error (errno).
int wait_for(int fd, short events) {
  pollfd entry{fd, events, 0};
  const int ready = ::poll(&entry, 1, kWaitMilliseconds);
  return ready < 0 && errno == EINTR ? 0 : ready;
}

// Whether the start of a text shows that it is no JSON object: its first character after white
// space (and a UTF-8 byte-order mark, which the parser skips) is there and is not '{'.
bool cannot_be_json_object(std::string_view text) {
  constexpr std::string_view kByteOrderMark = "\xEF\xBB\xBF";
  std::size_t at = 0;
  if (text.size() < kByteOrderMark.size() && kByteOrderMark.substr(0, text.size()) == text) return false;
  if (text.substr(0, kByteOrderMark.size()) == kByteOrderMark) at = kByteOrderMark.size();
  at = text.find_first_not_of(" \t\r\n", at);
  return at != std::string_view::npos && text[at] != '{';
}

Error too_large(const std::string& path, const std::string& what, std::uint64_t limit) {
  return Error{path + ": larger than " + format_bytes(static_cast<double>(limit)) + ", the most flatland reads as a " +
               what + " (docs/limits.md); is this the right file?"};
}

// A path for a message, its NUL characters shown as \0.
std::string printable(const std::string& path) {
  std::string shown;
  for (const char c : path) shown += c == '\0' ? std::string("\\0") : std::string(1, c);
  return shown;
}

fs::path directory_of(const fs::path& target) {
  return target.parent_path().empty() ? fs::path(".") : target.parent_path();
}

// Whether this process may write to `path` (by its effective user, as the kernel decides).
bool may_access(const std::string& path, int mode) {
  return ::faccessat(AT_FDCWD, path.c_str(), mode, AT_EACCESS) == 0;
}

}  // namespace

Result<std::string> read_input_file(const std::string& path, const std::string& what, const std::atomic<bool>* cancel,
                                    InputContent content, std::uint64_t limit) {
  if (path.empty()) return Error{"an empty path names no " + what + "; give the path of a .json file"};
  // The system reads a path up to its first NUL: "a.json\0junk" would open a.json.
  if (path.find('\0') != std::string::npos) return Error{printable(path) + ": a file name cannot hold a NUL character"};
  // Not blocking in open: a FIFO with no writer would hold open() in the kernel, deaf to a cancel.
  int opened = -1;
  do {
    opened = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  } while (opened < 0 && errno == EINTR);
  if (opened < 0) return Error{path + ": cannot read the " + what + ": " + reason(errno)};
  const Descriptor fd(opened);
  struct stat info {};
  if (::fstat(fd.get(), &info) != 0) return Error{path + ": cannot read the " + what + ": " + reason(errno)};
  if (S_ISDIR(info.st_mode)) return Error{path + ": is a directory, not a " + what + "; give the path of a .json file"};
  const bool regular = S_ISREG(info.st_mode);
  std::string text;
  if (regular) {
    if (static_cast<std::uint64_t>(info.st_size) > limit) return too_large(path, what, limit);
    text.reserve(static_cast<std::size_t>(info.st_size));
  }
  std::string buffer(std::size_t{1} << 16, '\0');
  for (;;) {
    // A pipe or device is read only when poll says so: a FIFO whose writer has not come yet reads
    // as at its end, while poll waits for the writer.
    if (!regular) {
      if (is_set(cancel)) return Error{kFileWaitCancelled};
      const int ready = wait_for(fd.get(), POLLIN);
      if (ready < 0) return Error{path + ": cannot read the " + what + ": " + reason(errno)};
      if (ready == 0) continue;
    }
    const ssize_t got = ::read(fd.get(), buffer.data(), buffer.size());
    if (got > 0) {
      if (text.size() + static_cast<std::size_t>(got) > limit) return too_large(path, what, limit);
      text.append(buffer.data(), static_cast<std::size_t>(got));
      if (!regular && content == InputContent::JsonObject && cannot_be_json_object(text)) break;
      continue;
    }
    if (got == 0) break;
    if (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK) continue;
    return Error{path + ": cannot read the " + what + ": " + reason(errno)};
  }
  return text;
}

std::optional<FileIdentity> existing_file_identity(const std::string& path) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) return std::nullopt;
  return FileIdentity{info.st_dev, info.st_ino, {}};
}

Result<OutputTarget> examine_output(const std::string& path) {
  OutputTarget target;
  target.path = path;
  if (path.find('\0') != std::string::npos) return Error{printable(path) + ": a file name cannot hold a NUL character"};
  struct stat standard_output {};
  const bool have_standard_output = ::fstat(STDOUT_FILENO, &standard_output) == 0;
  if (path == "-") {
    if (!have_standard_output) return Error{"-: the standard output is closed; give a file name"};
    target.kind = OutputKind::StandardStream;
    target.descriptor = STDOUT_FILENO;
    target.identity = {standard_output.st_dev, standard_output.st_ino, {}};
    target.shares_standard_output = true;
    return target;
  }
  const fs::path given(path);
  if (path.empty() || given.filename().empty() || given.filename() == "." || given.filename() == "..")
    return Error{path + ": not a file name; give a path such as out/result.json"};
  struct stat link {};
  if (::lstat(path.c_str(), &link) != 0) {
    if (errno != ENOENT) {
      if (errno == ENOTDIR) return Error{path + ": a part of the path before the name is not a directory"};
      return Error{path + ": cannot write it: " + reason(errno)};
    }
    const fs::path directory = directory_of(given);
    struct stat folder {};
    if (::stat(directory.c_str(), &folder) != 0) {
      if (errno == ENOENT)
        return Error{path + ": directory " + directory.string() + " does not exist; create it first"};
      return Error{path + ": cannot reach directory " + directory.string() + ": " + reason(errno)};
    }
    if (!S_ISDIR(folder.st_mode)) return Error{path + ": " + directory.string() + " is not a directory"};
    if (!may_access(directory.string(), W_OK | X_OK))
      return Error{path + ": cannot write in directory " + directory.string() + ": " + reason(errno)};
    target.kind = OutputKind::NewFile;
    target.real_path = path;
    target.identity = {folder.st_dev, folder.st_ino, given.filename().string()};
    return target;
  }
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) {
    if (S_ISLNK(link.st_mode)) {
      std::error_code ec;
      const fs::path points_to = fs::read_symlink(given, ec);
      return Error{path + ": is a symbolic link to " + (ec ? std::string("a file") : points_to.string()) +
                   ", which does not exist; give the path of the file to write"};
    }
    return Error{path + ": cannot write it: " + reason(errno)};
  }
  if (S_ISDIR(info.st_mode)) return Error{path + ": is a directory; give a file name"};
  target.identity = {info.st_dev, info.st_ino, {}};
  // What a standard stream already writes to (stdout redirected to this file or pipe): written to
  // that descriptor where it stands, not replaced under it or truncated from its start.
  for (const int descriptor : {STDOUT_FILENO, STDERR_FILENO}) {
    struct stat stream {};
    if (::fstat(descriptor, &stream) != 0 || stream.st_dev != info.st_dev || stream.st_ino != info.st_ino) continue;
    if (!S_ISREG(stream.st_mode) && !S_ISFIFO(stream.st_mode) && !S_ISSOCK(stream.st_mode)) continue;
    target.kind = OutputKind::StandardStream;
    target.descriptor = descriptor;
    target.real_path = path;
    target.shares_standard_output = descriptor == STDOUT_FILENO;
    return target;
  }
  if (S_ISREG(info.st_mode)) {
    std::error_code ec;
    target.real_path = S_ISLNK(link.st_mode) ? fs::canonical(given, ec).string() : path;
    if (ec) return Error{path + ": cannot follow the symbolic link: " + ec.message()};
    const fs::path directory = directory_of(target.real_path);
    struct stat folder {};
    if (::stat(directory.c_str(), &folder) != 0 || !may_access(directory.string(), W_OK | X_OK))
      return Error{path + ": cannot replace it: cannot write in directory " + directory.string() + ": " +
                   reason(errno)};
    // In a sticky directory (as /tmp) only the file's owner, the directory's owner or root may
    // rename over a file: rename() would refuse it after the work.
    const uid_t user = ::geteuid();
    if ((folder.st_mode & S_ISVTX) != 0 && user != 0 && info.st_uid != user && folder.st_uid != user)
      return Error{path +
                   ": cannot replace it: it belongs to another user, in a directory where only a "
                   "file's owner may replace it (sticky, as /tmp); give another name"};
    target.kind = OutputKind::ReplacedFile;
    return target;
  }
  if (S_ISCHR(info.st_mode) || S_ISFIFO(info.st_mode)) {
    if (!may_access(path, W_OK)) return Error{path + ": cannot write to it: " + reason(errno)};
    target.kind = OutputKind::WrittenThrough;
    target.real_path = path;
    target.discards = S_ISCHR(info.st_mode) && info.st_rdev == makedev(1, 3);
    target.shares_standard_output = have_standard_output && standard_output.st_dev == info.st_dev &&
                                    standard_output.st_ino == info.st_ino && ::isatty(STDOUT_FILENO) == 1;
    return target;
  }
  if (S_ISBLK(info.st_mode))
    return Error{path +
                 ": is a block device (a disk); flatland writes files, devices such as /dev/null, "
                 "FIFOs and - (the standard output)"};
  return Error{path + ": is a socket; give a file name, a FIFO or - (the standard output)"};
}

Status check_output_file(const std::string& path) {
  Result<OutputTarget> target = examine_output(path);
  if (!target) return target.error();
  return ok_status();
}

namespace {

// Our temporary names: temporary_prefix(target) + PID + "-" + digits.
std::string temporary_prefix(const fs::path& target) {
  // (Appended piece by piece: GCC 12 warns falsely about `"." + std::string` under -O3.)
  std::string prefix = ".";
  prefix += target.filename().string();
  prefix += ".tmp";
  return prefix;
}

// Removes temporary files of `target` whose writing process is gone (killed mid-write).
void remove_stale_temporaries(const fs::path& target) {
  const std::string prefix = temporary_prefix(target);
  std::error_code ec;
  for (fs::directory_iterator it(directory_of(target), ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string rest = name.substr(prefix.size());
    const std::size_t dash = rest.find('-');
    if (dash == 0 || dash == std::string::npos || dash + 1 == rest.size() ||
        rest.find_first_not_of("0123456789-") != std::string::npos || rest.find('-', dash + 1) != std::string::npos)
      continue;
    const long pid = std::strtol(rest.substr(0, dash).c_str(), nullptr, 10);
    if (pid <= 0 || pid == ::getpid()) continue;
    if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;  // still running
    std::error_code ignored;
    fs::remove(it->path(), ignored);
  }
}

// Writes all of `contents` to `fd`, which `target` names in errors. Each write waits for poll to
// say the descriptor takes data, watching `cancel` every kWaitMilliseconds. A standard stream is
// shared with other processes and never switched to non-blocking: its pieces are at most PIPE_BUF
// bytes, which a pipe that polls writable takes without blocking as long as nobody else writes to
// it at the same moment (a pipe shared with another writer, or a stopped terminal, can still hold
// a write up).

Status write_all(int fd, const OutputTarget& target, std::string_view contents, const std::atomic<bool>* cancel,
                 bool blocking) {
  struct stat info {};
  const bool regular = ::fstat(fd, &info) == 0 && S_ISREG(info.st_mode);
  const std::size_t piece = regular || !blocking ? std::size_t{1} << 20 : PIPE_BUF;
  std::size_t done = 0;
  while (done < contents.size()) {
    if (!regular) {
      if (is_set(cancel)) return Error{kFileWaitCancelled};
      const int ready = wait_for(fd, POLLOUT);
      if (ready < 0) return Error{target.path + ": write failed: " + reason(errno)};
      if (ready == 0) continue;
    }
    const ssize_t wrote = ::write(fd, contents.data() + done, std::min(piece, contents.size() - done));
    if (wrote > 0) {
      done += static_cast<std::size_t>(wrote);
      continue;
    }
    if (wrote < 0 && (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK)) continue;
    if (wrote < 0 && errno == EPIPE)
      return Error{target.path + ": the reader closed the pipe before the output was all written"};
    return Error{target.path + ": write failed: " + reason(wrote < 0 ? errno : EIO)};
  }
  return ok_status();
}

// Opens a device or FIFO and writes `contents` through it. A FIFO with no reader yet refuses a
// non-blocking open (ENXIO): it is tried again every kWaitMilliseconds until a reader comes or
// `cancel` is set.
Status write_through(const OutputTarget& target, std::string_view contents, const std::atomic<bool>* cancel) {
  if (target.kind == OutputKind::StandardStream) return write_all(target.descriptor, target, contents, cancel, true);
  int opened = -1;
  for (;;) {
    opened = ::open(target.real_path.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if (opened >= 0) break;
    if (errno == EINTR) continue;
    if (errno != ENXIO) return Error{target.path + ": cannot open it for writing: " + reason(errno)};
    if (is_set(cancel)) return Error{kFileWaitCancelled};
    ::poll(nullptr, 0, kWaitMilliseconds);
  }
  const Descriptor fd(opened);
  // The same device or FIFO that was examined: a regular file put in its place since would be
  // written over from its start, neither replaced whole nor truncated.
  struct stat info {};
  if (::fstat(fd.get(), &info) != 0 || !(S_ISCHR(info.st_mode) || S_ISFIFO(info.st_mode)) ||
      info.st_dev != target.identity.device || info.st_ino != target.identity.inode)
    return Error{target.path + ": changed since it was checked (no longer the device or FIFO it was); nothing written"};
  return write_all(fd.get(), target, contents, cancel, false);
}

// Writes `contents` to a new file with a unique temporary name beside `target` (same directory,
// so the rename is atomic), with the permissions of the file it will replace, if any.
Result<std::string> write_temporary(const OutputTarget& target, std::string_view contents) {
  const fs::path real(target.real_path);
  remove_stale_temporaries(real);
  std::random_device device;
  std::string name = temporary_prefix(real);
  name += std::to_string(::getpid());
  name += '-';
  name += std::to_string(device());
  const std::string temporary = (directory_of(real) / name).string();
  int opened = -1;
  do {
    opened = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  } while (opened < 0 && errno == EINTR);
  if (opened < 0) return Error{target.path + ": cannot write: " + reason(errno)};
  Status written = ok_status();
  {
    struct stat replaced {};
    if (target.kind == OutputKind::ReplacedFile && ::stat(target.real_path.c_str(), &replaced) == 0)
      (void)::fchmod(opened, replaced.st_mode & 0777);
    written = write_all(opened, target, contents, nullptr, false);
    // On the disk before the rename, so that a crash leaves the old file or the new one, never an
    // empty one; and a failure the file system reports only now (NFS, quotas) is an error here.
    if (written && ::fsync(opened) != 0) written = Error{target.path + ": write failed: " + reason(errno)};
    if (::close(opened) != 0 && written) written = Error{target.path + ": write failed: " + reason(errno)};
  }
  if (!written) {
    std::error_code ignored;
    fs::remove(temporary, ignored);
    return written.error();
  }
  return temporary;
}

bool is_renamed(OutputKind kind) { return kind == OutputKind::NewFile || kind == OutputKind::ReplacedFile; }

}  // namespace

OutputFiles::~OutputFiles() { discard(); }

void OutputFiles::discard() {
  for (const Staged& file : staged_) {
    if (file.temporary.empty()) continue;
    std::error_code ignored;
    fs::remove(file.temporary, ignored);
  }
  staged_.clear();
}

Status OutputFiles::stage(const std::string& path, std::string contents) {
  Result<OutputTarget> target = examine_output(path);
  if (!target) return target.error();
  Staged staged{std::move(*target), {}, {}};
  if (is_renamed(staged.target.kind)) {
    Result<std::string> temporary = write_temporary(staged.target, contents);
    if (!temporary) return temporary.error();
    staged.temporary = std::move(*temporary);
  } else {
    staged.contents = std::move(contents);
  }
  staged_.push_back(std::move(staged));
  return ok_status();
}

Status OutputFiles::commit() {
  for (std::size_t i = 0; i < staged_.size(); ++i) {
    Staged& file = staged_[i];
    Status done = ok_status();
    if (is_renamed(file.target.kind)) {
      std::error_code ec;
      fs::rename(file.temporary, file.target.real_path, ec);
      if (ec)
        done = Error{file.target.path + ": cannot replace the file: " + ec.message()};
      else
        file.temporary.clear();
    } else {
      done = write_through(file.target, file.contents, cancel_);
    }
    if (!done) {
      discard();
      return done;
    }
  }
  staged_.clear();
  return ok_status();
}

Status write_file_atomically(const std::string& path, const std::string& contents, const std::atomic<bool>* cancel) {
  OutputFiles files(cancel);
  if (Status status = files.stage(path, contents); !status) return status;
  return files.commit();
}

}  // namespace flatland
