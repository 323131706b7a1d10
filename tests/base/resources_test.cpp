// The machine's memory and this process's limits (base/resources.hpp), read as the work reads
// them; a limited process is made in a child, so the test's own limits never change.
#include "flatland/base/resources.hpp"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>

#include <gtest/gtest.h>

namespace flatland {
namespace {

TEST(Resources, BytesReadAsPeopleWriteThem) {
  EXPECT_EQ(format_bytes(820e6), "820 MB");
  EXPECT_EQ(format_bytes(1.5e9), "1.5 GB");
  EXPECT_EQ(format_bytes(1.76e12), "1.76 TB");
  EXPECT_EQ(format_bytes(512.0), "0.512 kB");
}

// Without limits the budget is three quarters of the physical memory at most; a thread's stack is
// what RLIMIT_STACK says (or 8 MiB when it is unlimited).
TEST(Resources, BudgetAndStacksFollowTheMachineAndItsLimits) {
  const std::size_t physical =
      static_cast<std::size_t>(::sysconf(_SC_PHYS_PAGES)) * static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  EXPECT_LE(default_memory_budget(), physical / 4 * 3 + 4096);
  EXPECT_GT(default_memory_budget(), 0u);
  rlimit stack{};
  ASSERT_EQ(::getrlimit(RLIMIT_STACK, &stack), 0);
  if (stack.rlim_cur == RLIM_INFINITY)
    EXPECT_EQ(thread_stack_bytes(), std::size_t{8} << 20);
  else
    EXPECT_EQ(thread_stack_bytes(), std::max<std::size_t>(stack.rlim_cur, std::size_t{64} << 10));
}

// Under an address-space limit what is left is the limit less what is mapped, and the budget is at
// most half of that: checked in a child process that lowers its own limit.
TEST(Resources, AnAddressSpaceLimitBoundsTheBudget) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer maps more address space than any such limit allows";
#endif
  const pid_t child = ::fork();
  if (child == 0) {
    const std::size_t unlimited = address_space_left();
    rlimit limit{};
    ::getrlimit(RLIMIT_AS, &limit);
    limit.rlim_cur = static_cast<rlim_t>(8) << 30;  // 8 GiB
    if (unlimited != SIZE_MAX || ::setrlimit(RLIMIT_AS, &limit) != 0) ::_exit(3);
    const std::size_t left = address_space_left();
    const bool sensible = left < (std::size_t{8} << 30) && left > (std::size_t{7} << 30);
    ::_exit(sensible && default_memory_budget() <= left / 2 ? 0 : 1);
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  if (WEXITSTATUS(status) == 3) GTEST_SKIP() << "this process already runs under an address-space limit";
  EXPECT_EQ(WEXITSTATUS(status), 0);
}

}  // namespace
}  // namespace flatland
