// src/mpi: the processes of an MPI run. This executable runs under `mpirun -np K` (ctest starts it
// so); every process runs every test, and each test's collective calls are made by all of them.
#include "mpi/world.hpp"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/transport/error_estimate.hpp"
#include "flatland/transport/solver.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

mpi::World* world = nullptr;

// The sum is exact integer addition over the processes, in place, for vectors of any length.
TEST(Mpi, SumAddsEveryProcessesIntegersExactly) {
  const std::int64_t k = world->size();
  const std::int64_t r = world->rank();
  std::vector<std::int64_t> values{r, 1, (std::int64_t{1} << 52) + r, -3 * r};
  world->sum(values);
  EXPECT_EQ(values[0], k * (k - 1) / 2);
  EXPECT_EQ(values[1], k);
  EXPECT_EQ(values[2], k * (std::int64_t{1} << 52) + k * (k - 1) / 2);
  EXPECT_EQ(values[3], -3 * k * (k - 1) / 2);
  std::vector<std::int64_t> empty;
  world->sum(empty);
  std::vector<std::int64_t> large(1 << 20, r + 1);
  world->sum(large);
  EXPECT_EQ(large.front(), k * (k + 1) / 2);
  EXPECT_EQ(large.back(), k * (k + 1) / 2);
}

testing::SolutionData dump(const Solver& solver) { return testing::solution_data(solver); }

// Every process solves alone and then with the others sharing the rounds: the shared solve has the
// bits of the lone one, for shooting (points, footprints, colour) and walks, on any thread count.
TEST(Mpi, SharedSolveHasTheBitsOfOneProcess) {
  for (const testing::SharingCase& c : testing::kSharingCases) {
    SCOPED_TRACE(c.scene);
    const Scene scene = testing::scene_from_file(c.scene);
    SolverSettings settings = testing::sharing_settings(c, 200'000, 11);
    Result<Solver> alone = Solver::create(scene, settings);
    ASSERT_TRUE(alone.ok());
    alone->run();
    settings.threads = c.ray_width > 0.0 ? 2 : 1;  // threads within processes too
    Result<Solver> shared = Solver::create(scene, settings);
    ASSERT_TRUE(shared.ok());
    shared->share_rounds(world);
    const std::uint64_t bytes_before = world->bytes_summed();
    shared->run();
    EXPECT_GT(shared->rounds(), 1u);
    EXPECT_EQ(dump(*shared), dump(*alone));
    // And so is the estimated error, which reads only the solve's state.
    const ErrorEstimate shared_estimate = estimate_error(*shared);
    const ErrorEstimate alone_estimate = estimate_error(*alone);
    EXPECT_EQ(shared_estimate.bound.l1, alone_estimate.bound.l1);
    EXPECT_EQ(shared_estimate.bound.linf, alone_estimate.bound.linf);
    EXPECT_EQ(shared->photons_shot(), alone->photons_shot());
    // One message per round: the deposits (once per replicate), the detectors' tallies and 22 counters
    // (escaped, absorbed, shot and the three chain losses per channel, chains cut, rays, photons, cancel).
    const std::uint64_t per_round = (shared->coefficient_count() * static_cast<std::uint64_t>(scene.channels) *
                                         static_cast<std::uint64_t>(settings.replicates) +
                                     shared->detector_layout().size + 22) *
                                    8;
    EXPECT_EQ(world->bytes_summed() - bytes_before, per_round * shared->rounds());
    EXPECT_EQ(shared->bytes_shared(), per_round * shared->rounds());
  }
}

}  // namespace
}  // namespace flatland

int main(int argc, char** argv) {
  flatland::mpi::World world(&argc, &argv);
  flatland::world = &world;
  ::testing::InitGoogleTest(&argc, argv);
  if (world.size() < 2) std::printf("note: one process; ctest runs this under mpirun -np 2 and 3\n");
  return RUN_ALL_TESTS();
}
