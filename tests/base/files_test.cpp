// Files a command reads and writes (files.hpp): inputs of every kind read with a limit and a
// cancel, outputs written all or nothing, devices and pipes written through and never replaced.
// Device nodes are made by the test itself (mknod, as root) in its own directory, never the
// machine's /dev.
#include "flatland/base/files.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "test_support.hpp"

namespace flatland {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

class Files : public testing::ScratchDirectoryTest {
 protected:
  Files() : ScratchDirectoryTest("flatland-files") {}
  std::vector<std::string> names() const {
    std::vector<std::string> found;
    for (const auto& entry : fs::directory_iterator(directory_)) found.push_back(entry.path().filename().string());
    std::sort(found.begin(), found.end());
    return found;
  }
  std::string path(const std::string& name) const { return (directory_ / name).string(); }
  // A character device node of the test's own (1, minor: 3 null, 5 zero, 7 full), or "" when the
  // test cannot make one (not root).
  std::string device(const std::string& name, unsigned minor) const {
    if (::geteuid() != 0) return {};
    const std::string node = path(name);
    if (::mknod(node.c_str(), S_IFCHR | 0666, makedev(1, minor)) != 0) return {};
    // (On a file system mounted nodev a node is made but cannot be opened.)
    const int fd = ::open(node.c_str(), O_RDONLY | O_NONBLOCK);
    if (fd < 0) {
      fs::remove(node);
      return {};
    }
    ::close(fd);
    return node;
  }
  std::string fifo(const std::string& name) const {
    const std::string node = path(name);
    EXPECT_EQ(::mkfifo(node.c_str(), 0600), 0);
    return node;
  }
};

bool is_character_device(const std::string& path) {
  struct stat info {};
  return ::lstat(path.c_str(), &info) == 0 && S_ISCHR(info.st_mode);
}

// ---- inputs -------------------------------------------------------------------------------

TEST_F(Files, ReadsARegularFileWhole) {
  const std::string text = "{\"a\": [" + std::string(200'000, ' ') + "1]}";
  std::ofstream(path("a.json")) << text;
  Result<std::string> read = read_input_file(path("a.json"), "scene file");
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(*read, text);
}

TEST_F(Files, MissingDirectoryAndTooLargeInputsAreOneLineErrors) {
  const Result<std::string> missing = read_input_file(path("none.json"), "scene file");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().message, path("none.json") + ": cannot read the scene file: No such file or directory");
  const Result<std::string> directory = read_input_file(directory_.string(), "result file");
  ASSERT_FALSE(directory.ok());
  EXPECT_NE(directory.error().message.find("is a directory, not a result file"), std::string::npos);
  // A regular file past the limit is refused from its size, before it is read.
  std::ofstream(path("big.json")) << std::string(2000, ' ');
  const Result<std::string> big =
      read_input_file(path("big.json"), "scene file", nullptr, InputContent::JsonObject, 1000);
  ASSERT_FALSE(big.ok());
  EXPECT_NE(big.error().message.find("larger than"), std::string::npos) << big.error().message;
  EXPECT_TRUE(read_input_file(path("big.json"), "scene file", nullptr, InputContent::JsonObject, 2000).ok());
}

// The system reads a path up to its first NUL; "a.json\0junk" must not open a.json.
TEST_F(Files, PathsWithANulCharacterAreRefused) {
  std::ofstream(path("a.json")) << "{}";
  const std::string with_nul = path("a.json") + std::string(1, '\0') + "junk";
  const Result<std::string> read = read_input_file(with_nul, "scene file");
  ASSERT_FALSE(read.ok());
  EXPECT_NE(read.error().message.find("NUL"), std::string::npos) << read.error().message;
  EXPECT_FALSE(examine_output(with_nul).ok());
}

// A FIFO whose writer never comes is waited for, and the wait ends when the cancel flag is set.
TEST_F(Files, AWaitForAPipeEndsWhenCancelled) {
  const std::string node = fifo("in.json");
  std::atomic<bool> cancel{false};
  std::thread interrupt([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    cancel.store(true);
  });
  const Clock::time_point start = Clock::now();
  const Result<std::string> read = read_input_file(node, "scene file", &cancel);
  const double waited = seconds_since(start);
  interrupt.join();
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.error().message, kFileWaitCancelled);
  EXPECT_GE(waited, 0.15);
  EXPECT_LT(waited, 1.0);
}

// A writer that comes late and writes in pieces is read to its end.
TEST_F(Files, APipeIsReadToItsEnd) {
  const std::string node = fifo("in.json");
  const std::string text = "{\"curves\": [" + std::string(300'000, ' ') + "]}";
  std::thread writer([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    std::ofstream out(node);
    for (std::size_t at = 0; at < text.size(); at += 70'000) {
      out << text.substr(at, 70'000);
      out.flush();
    }
  });
  const Result<std::string> read = read_input_file(node, "scene file");
  writer.join();
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(*read, text);
}

// A stream past the limit is refused once the limit is passed, not read to its end.
TEST_F(Files, AStreamPastTheLimitIsRefused) {
  const std::string node = fifo("in.json");
  std::thread writer([&] {
    std::ofstream out(node);
    out << "{" << std::string(5000, ' ');
  });
  const Result<std::string> read = read_input_file(node, "scene file", nullptr, InputContent::JsonObject, 1000);
  writer.join();
  ASSERT_FALSE(read.ok());
  EXPECT_NE(read.error().message.find("larger than"), std::string::npos) << read.error().message;
}

// A device of endless zeros: no JSON object can start with a NUL byte, so the reading stops after
// its first piece instead of filling memory; the parser then reports that byte.
TEST_F(Files, AnEndlessDeviceStopsAtItsFirstCharacter) {
  const std::string zero = device("zero", 5);
  if (zero.empty()) GTEST_SKIP() << "making a device node needs root";
  const Clock::time_point start = Clock::now();
  const Result<std::string> read = read_input_file(zero, "scene file");
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_LE(read->size(), std::size_t{1} << 16);
  EXPECT_EQ(read->find_first_not_of('\0'), std::string::npos);
  EXPECT_LT(seconds_since(start), 1.0);
  // As text (a table, say) it is read up to the limit and refused.
  const Result<std::string> text = read_input_file(zero, "table", nullptr, InputContent::Text, 1 << 20);
  ASSERT_FALSE(text.ok());
  EXPECT_NE(text.error().message.find("larger than"), std::string::npos);
}

// ---- outputs ------------------------------------------------------------------------------

TEST_F(Files, OutputPathsAreCheckedBeforeWork) {
  EXPECT_TRUE(check_output_file(path("r.json")).ok());
  const Status missing = check_output_file(path("no/r.json"));
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("does not exist"), std::string::npos) << missing.error().message;
  const Status directory = check_output_file(directory_.string());
  ASSERT_FALSE(directory.ok());
  EXPECT_NE(directory.error().message.find("is a directory"), std::string::npos);
  EXPECT_FALSE(check_output_file("").ok());
  std::ofstream(path("file")) << "x";
  const Status under_a_file = check_output_file(path("file/r.json"));
  ASSERT_FALSE(under_a_file.ok());
  EXPECT_NE(under_a_file.error().message.find("not a directory"), std::string::npos) << under_a_file.error().message;
  fs::remove(path("file"));
  EXPECT_TRUE(names().empty());  // checking writes nothing
}

TEST_F(Files, StagedFilesAppearOnlyOnCommit) {
  {
    OutputFiles outputs;
    ASSERT_TRUE(outputs.stage(path("a.json"), "{}\n").ok());
    ASSERT_TRUE(outputs.stage(path("b.png"), "png").ok());
    EXPECT_FALSE(fs::exists(path("a.json")));
    EXPECT_EQ(names().size(), 2u);  // two temporaries
  }
  // Dropped without a commit (an interrupt, an error): nothing is left, not even temporaries.
  EXPECT_TRUE(names().empty());
  OutputFiles outputs;
  ASSERT_TRUE(outputs.stage(path("a.json"), "{}\n").ok());
  ASSERT_TRUE(outputs.stage(path("b.png"), "png").ok());
  ASSERT_TRUE(outputs.commit().ok());
  EXPECT_EQ(names(), (std::vector<std::string>{"a.json", "b.png"}));
  EXPECT_EQ(testing::read_text_file(path("b.png")), "png");
}

// SIGKILL during a write leaves .NAME.tmpPID-RANDOM behind; the next write of NAME removes those
// whose process is gone, and leaves a running process's alone.
TEST_F(Files, StaleTemporariesOfDeadProcessesAreRemoved) {
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  int status = 0;
  ::waitpid(child, &status, 0);  // `child` now names no process
  const std::string dead = ".r.json.tmp" + std::to_string(child) + "-12345";
  const std::string alive = ".r.json.tmp" + std::to_string(::getppid()) + "-777";
  const std::string other = ".s.json.tmp" + std::to_string(child) + "-1";  // another target's
  for (const std::string& name : {dead, alive, other}) std::ofstream(directory_ / name) << "partial";
  ASSERT_TRUE(write_file_atomically(path("r.json"), "{}\n").ok());
  EXPECT_EQ(names(), (std::vector<std::string>{alive, other, "r.json"}));
}

// A regular file is replaced whole and keeps its permissions; through a symbolic link, the file
// the link names is replaced and the link stays a link; a link to nothing is refused.
TEST_F(Files, ReplacedFilesKeepTheirModeAndLinksStayLinks) {
  std::ofstream(path("r.json")) << "old";
  ::chmod(path("r.json").c_str(), 0600);
  ASSERT_TRUE(write_file_atomically(path("r.json"), "new").ok());
  EXPECT_EQ(testing::read_text_file(path("r.json")), "new");
  struct stat info {};
  ASSERT_EQ(::stat(path("r.json").c_str(), &info), 0);
  EXPECT_EQ(info.st_mode & 0777, 0600u);

  fs::create_symlink("r.json", path("link.json"));
  Result<OutputTarget> target = examine_output(path("link.json"));
  ASSERT_TRUE(target.ok()) << target.error().message;
  EXPECT_EQ(target->kind, OutputKind::ReplacedFile);
  EXPECT_EQ(target->real_path, fs::canonical(path("r.json")).string());
  ASSERT_TRUE(write_file_atomically(path("link.json"), "through the link").ok());
  EXPECT_TRUE(fs::is_symlink(path("link.json")));
  EXPECT_EQ(testing::read_text_file(path("r.json")), "through the link");

  fs::create_symlink("nowhere.json", path("dangling.json"));
  const Status dangling = check_output_file(path("dangling.json"));
  ASSERT_FALSE(dangling.ok());
  EXPECT_NE(dangling.error().message.find("nowhere.json, which does not exist"), std::string::npos)
      << dangling.error().message;
  EXPECT_FALSE(fs::exists(path("nowhere.json")));
}

// Two spellings of one file have one identity; a file not yet made is named by its directory and name.
TEST_F(Files, IdentitiesFollowFilesNotSpellings) {
  std::ofstream(path("a.json")) << "{}";
  fs::create_directory(path("sub"));
  const std::string other_spelling = path("sub/../a.json");
  ASSERT_TRUE(existing_file_identity(other_spelling).has_value());
  EXPECT_EQ(*existing_file_identity(path("a.json")), *existing_file_identity(other_spelling));
  Result<OutputTarget> made = examine_output(path("new.json"));
  Result<OutputTarget> also = examine_output(path("sub/../new.json"));
  ASSERT_TRUE(made.ok() && also.ok());
  EXPECT_EQ(made->identity, also->identity);
  Result<OutputTarget> existing = examine_output(other_spelling);
  ASSERT_TRUE(existing.ok());
  EXPECT_EQ(existing->identity, *existing_file_identity(path("a.json")));
}

// "-" is the standard output, written where it stands.
TEST_F(Files, DashIsTheStandardOutput) {
  Result<OutputTarget> target = examine_output("-");
  ASSERT_TRUE(target.ok()) << target.error().message;
  EXPECT_EQ(target->kind, OutputKind::StandardStream);
  EXPECT_EQ(target->descriptor, STDOUT_FILENO);
  EXPECT_TRUE(target->shares_standard_output);
}

// A device node is written through and stays a device: a rename over it would replace the node
// with a regular file (for /dev/null, breaking the machine). A full device gives an error.
TEST_F(Files, DevicesAreWrittenThroughAndNeverReplaced) {
  const std::string null = device("null", 3);
  const std::string full = device("full", 7);
  if (null.empty() || full.empty()) GTEST_SKIP() << "making a device node needs root";
  Result<OutputTarget> target = examine_output(null);
  ASSERT_TRUE(target.ok()) << target.error().message;
  EXPECT_EQ(target->kind, OutputKind::WrittenThrough);
  ASSERT_TRUE(write_file_atomically(null, std::string(3'000'000, 'x')).ok());
  EXPECT_TRUE(is_character_device(null));
  const Status no_space = write_file_atomically(full, "{}\n");
  ASSERT_FALSE(no_space.ok());
  EXPECT_NE(no_space.error().message.find("No space left"), std::string::npos) << no_space.error().message;
  EXPECT_TRUE(is_character_device(full));
  EXPECT_EQ(names(), (std::vector<std::string>{"full", "null"}));  // no temporaries either
  // A disk is never written.
  const std::string disk = path("disk");
  ASSERT_EQ(::mknod(disk.c_str(), S_IFBLK | 0600, makedev(7, 0)), 0);
  const Status refused = check_output_file(disk);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("block device"), std::string::npos);
}

// A FIFO is written through once a reader comes; with none, the wait ends when cancelled.
TEST_F(Files, PipesAreWrittenThroughAndWaitingForAReaderCanBeCancelled) {
  const std::string node = fifo("out.json");
  const std::string text(200'000, 'r');
  std::string received;
  std::thread reader([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(150));
    received = testing::read_text_file(node);
  });
  ASSERT_TRUE(write_file_atomically(node, text).ok());
  reader.join();
  EXPECT_EQ(received, text);

  std::atomic<bool> cancel{false};
  std::thread interrupt([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    cancel.store(true);
  });
  const Clock::time_point start = Clock::now();
  const Status waited = write_file_atomically(node, text, &cancel);
  interrupt.join();
  ASSERT_FALSE(waited.ok());
  EXPECT_EQ(waited.error().message, kFileWaitCancelled);
  EXPECT_LT(seconds_since(start), 1.0);
}

// In a sticky directory (as /tmp) another user's file cannot be replaced: said when the path is
// examined, before any work, not after it by a failed rename. Run as an unprivileged user in a
// child process (root may replace anything).
TEST_F(Files, AnotherUsersFileInAStickyDirectoryIsRefusedUpFront) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root to act as two users";
  const fs::path sticky = directory_ / "sticky";
  fs::create_directory(sticky);
  ::chmod(directory_.c_str(), 0755);
  ::chmod(sticky.c_str(), 01777);
  std::ofstream(sticky / "theirs.json") << "{}";  // owned by root
  const pid_t child = ::fork();
  if (child == 0) {
    if (::setgid(65534) != 0 || ::setuid(65534) != 0) ::_exit(3);
    const Status theirs = check_output_file((sticky / "theirs.json").string());
    const Status mine = check_output_file((sticky / "mine.json").string());
    const bool refused = !theirs.ok() && theirs.error().message.find("belongs to another user") != std::string::npos;
    ::_exit(refused && mine.ok() ? 0 : 1);
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
}

}  // namespace
}  // namespace flatland
