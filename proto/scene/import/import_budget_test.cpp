// The import budget: reservations that fit, wait for room, are refused when none comes in
// time or when they could never fit, and always give back what they held.
#include "proto/scene/import/import_budget.h"

#include <gtest/gtest.h>

#include <atomic>
#include <future>
#include <thread>
#include <vector>

namespace tcfarm {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

TEST(ImportBudgetTest, AReservationHoldsItsBytesUntilItEnds) {
  ImportBudget budget(100);
  {
    ImportReservation held = budget.Reserve(60);
    EXPECT_EQ(held.bytes(), 60u);
    EXPECT_EQ(budget.Stats().reservedBytes, 60u);
    held.Grow(30);
    EXPECT_EQ(held.bytes(), 90u);
    EXPECT_EQ(budget.Stats().reservedBytes, 90u);
  }
  EXPECT_EQ(budget.Stats().reservedBytes, 0u);
  EXPECT_EQ(budget.Stats().peakReservedBytes, 90u);
  EXPECT_EQ(budget.Stats().waits, 0u);
}

TEST(ImportBudgetTest, AMovedReservationIsGivenBackOnce) {
  ImportBudget budget(100);
  ImportReservation first = budget.Reserve(40);
  ImportReservation second = std::move(first);
  EXPECT_EQ(first.bytes(), 0u);
  EXPECT_EQ(budget.Stats().reservedBytes, 40u);
  ImportReservation third = budget.Reserve(10);
  third = std::move(second);  // third's own 10 bytes are given back
  EXPECT_EQ(budget.Stats().reservedBytes, 40u);
  third = ImportReservation();
  EXPECT_EQ(budget.Stats().reservedBytes, 0u);
}

TEST(ImportBudgetTest, AReservationThatDoesNotFitWaitsForAnotherToEnd) {
  ImportBudget budget(100, 5s);
  auto held = std::make_unique<ImportReservation>(budget.Reserve(80));
  std::future<uint64_t> waiting = std::async(std::launch::async, [&] { return budget.Reserve(50).bytes(); });
  EXPECT_EQ(waiting.wait_for(50ms), std::future_status::timeout);
  held.reset();
  ASSERT_EQ(waiting.wait_for(5s), std::future_status::ready);
  EXPECT_EQ(waiting.get(), 50u);
  EXPECT_EQ(budget.Stats().waits, 1u);
  EXPECT_EQ(budget.Stats().refusals, 0u);
  EXPECT_EQ(budget.Stats().peakReservedBytes, 80u);
}

TEST(ImportBudgetTest, AReservationWithoutRoomInTimeIsBusyAndHoldsNothing) {
  ImportBudget budget(100, 100ms);
  const ImportReservation held = budget.Reserve(80);
  const Clock::time_point start = Clock::now();
  try {
    budget.Reserve(30);
    FAIL() << "a reservation past the budget was granted";
  } catch (const ImportBudgetBusyError& error) {
    EXPECT_EQ(error.retryAfter(), 1s);
    EXPECT_NE(std::string(error.what()).find("hold 80 bytes of its 100 bytes"), std::string::npos) << error.what();
  }
  EXPECT_GE(Clock::now() - start, 100ms);
  EXPECT_LT(Clock::now() - start, 2s);
  EXPECT_EQ(budget.Stats().reservedBytes, 80u);
  EXPECT_EQ(budget.Stats().refusals, 1u);
}

TEST(ImportBudgetTest, AGrowthWithoutRoomKeepsWhatWasHeld) {
  ImportBudget budget(100, 20ms);
  const ImportReservation other = budget.Reserve(50);
  ImportReservation held = budget.Reserve(40);
  EXPECT_THROW(held.Grow(20), ImportBudgetBusyError);
  EXPECT_EQ(held.bytes(), 40u);
  EXPECT_EQ(budget.Stats().reservedBytes, 90u);
}

// Waits until `budget` has seen `waits` reservations that could not be granted at once.
void AwaitWaits(const ImportBudget& budget, uint64_t waits) {
  const Clock::time_point deadline = Clock::now() + 5s;
  while (budget.Stats().waits < waits && Clock::now() < deadline) std::this_thread::sleep_for(1ms);
  ASSERT_GE(budget.Stats().waits, waits);
}

TEST(ImportBudgetTest, ANewImportDoesNotOvertakeAnOlderOneWaiting) {
  ImportBudget budget(100, 5s);
  ImportReservation older = budget.Reserve(50);
  auto running = std::make_unique<ImportReservation>(budget.Reserve(30));
  std::future<void> growing = std::async(std::launch::async, [&] { older.Grow(40); });
  AwaitWaits(budget, 1);
  // 10 bytes are free, but the older import waits for more: the new one queues behind it.
  std::future<uint64_t> newer = std::async(std::launch::async, [&] { return budget.Reserve(10).bytes(); });
  AwaitWaits(budget, 2);
  EXPECT_EQ(newer.wait_for(50ms), std::future_status::timeout);
  running.reset();
  ASSERT_EQ(growing.wait_for(5s), std::future_status::ready);
  ASSERT_EQ(newer.wait_for(5s), std::future_status::ready);
  EXPECT_EQ(newer.get(), 10u);
  EXPECT_EQ(older.bytes(), 90u);
  EXPECT_EQ(budget.Stats().refusals, 0u);
}

TEST(ImportBudgetTest, AYoungerImportHoldingMemoryGivesWayToAnOlderOneAtOnce) {
  ImportBudget budget(100, 5s);
  ImportReservation older = budget.Reserve(60);
  auto younger = std::make_unique<ImportReservation>(budget.Reserve(30));
  std::future<void> growing = std::async(std::launch::async, [&] { older.Grow(20); });
  AwaitWaits(budget, 1);
  const Clock::time_point start = Clock::now();
  EXPECT_THROW(younger->Grow(5), ImportBudgetBusyError);  // 10 bytes are free, but not for it
  EXPECT_LT(Clock::now() - start, 1s);
  younger.reset();  // the refused import ends, giving its part back
  ASSERT_EQ(growing.wait_for(5s), std::future_status::ready);
  EXPECT_EQ(older.bytes(), 80u);
}

TEST(ImportBudgetTest, AYoungerImportWaitingWithMemoryHeldGivesWayWhenAnOlderOneWaits) {
  ImportBudget budget(100, 5s);
  ImportReservation older = budget.Reserve(50);
  std::future<bool> younger = std::async(std::launch::async, [&] {
    ImportReservation held = budget.Reserve(40);
    try {
      held.Grow(20);  // waits: 10 bytes are free
      return true;
    } catch (const ImportBudgetBusyError&) {
      return false;
    }
  });
  AwaitWaits(budget, 1);
  const Clock::time_point start = Clock::now();
  older.Grow(20);  // the two would wait for each other; the younger gives way
  EXPECT_LT(Clock::now() - start, 1s);
  EXPECT_FALSE(younger.get());
  EXPECT_EQ(older.bytes(), 70u);
}

TEST(ImportBudgetTest, MoreThanTheWholeBudgetIsRefusedAtOnce) {
  ImportBudget budget(100, 5s);
  const Clock::time_point start = Clock::now();
  EXPECT_THROW(budget.Reserve(101), ImportTooLargeError);
  ImportReservation held = budget.Reserve(70);
  EXPECT_THROW(held.Grow(31), ImportTooLargeError);
  EXPECT_LT(Clock::now() - start, 1s);  // neither waited for room that cannot come
  EXPECT_EQ(held.bytes(), 70u);
  EXPECT_EQ(budget.Stats().refusals, 0u);
}

TEST(ImportBudgetTest, RetryAfterIsTheWaitInWholeSeconds) {
  EXPECT_EQ(ImportBudget(1, 2000ms).RetryAfter(), 2s);
  EXPECT_EQ(ImportBudget(1, 2001ms).RetryAfter(), 3s);
  EXPECT_EQ(ImportBudget(1, 0ms).RetryAfter(), 1s);
}

TEST(ImportBudgetTest, ChargesGrowTheScopesReservationAndNothingWithoutOne) {
  ImportBudget budget(100);
  ChargeImportMemory(1000);  // no scope: nothing to charge, nothing refused
  EXPECT_FALSE(ChargingImportMemory());
  ImportReservation outer = budget.Reserve(10);
  {
    const ImportMemoryScope scope(outer);
    EXPECT_TRUE(ChargingImportMemory());
    ChargeImportMemory(5);
    ImportReservation inner = budget.Reserve(0);
    {
      const ImportMemoryScope nested(inner);
      ChargeImportMemory(7);
    }
    ChargeImportMemory(3);  // the outer scope again
    EXPECT_EQ(inner.bytes(), 7u);
  }
  ChargeImportMemory(1000);
  EXPECT_FALSE(ChargingImportMemory());
  EXPECT_EQ(outer.bytes(), 18u);
  EXPECT_EQ(budget.Stats().reservedBytes, 18u);
}

TEST(ImportBudgetTest, MemoryFreedDuringTheImportIsHeldOnlyWhileItLives) {
  ImportBudget budget(100, 5s);
  EXPECT_EQ(ReserveImportMemory(1000).bytes(), 0u);  // no scope: nothing held, nothing refused
  ImportReservation held = budget.Reserve(30);
  const ImportMemoryScope scope(held);
  for (int texture = 0; texture < 10; ++texture) {
    const ImportReservation decoding = ReserveImportMemory(60);
    EXPECT_EQ(budget.Stats().reservedBytes, 90u);
  }
  EXPECT_EQ(budget.Stats().reservedBytes, 30u);
  // With what the import holds it could never fit: refused at once, not after a wait for itself.
  const Clock::time_point start = Clock::now();
  EXPECT_THROW(ReserveImportMemory(71), ImportTooLargeError);
  EXPECT_LT(Clock::now() - start, 1s);
}

TEST(ImportBudgetTest, AScopeChargesOnlyItsOwnThread) {
  ImportBudget budget(100);
  ImportReservation held = budget.Reserve(0);
  const ImportMemoryScope scope(held);
  std::thread([] { ChargeImportMemory(50); }).join();
  EXPECT_EQ(held.bytes(), 0u);
}

TEST(ImportBudgetTest, WorkWithinTheBudgetGivesItsBytesBackEvenWhenItThrows) {
  ImportBudget budget(100);
  EXPECT_EQ(WithinImportBudget(&budget, 20, [&] {
              ChargeImportMemory(30);
              return budget.Stats().reservedBytes;
            }),
            50u);
  EXPECT_THROW(WithinImportBudget(&budget, 20,
                                  [&]() -> int {
                                    ChargeImportMemory(30);
                                    throw std::runtime_error("bad file");
                                  }),
               std::runtime_error);
  EXPECT_EQ(budget.Stats().reservedBytes, 0u);
  EXPECT_EQ(WithinImportBudget(nullptr, 1000, [] { return 7; }), 7);
}

TEST(ImportBudgetTest, ConcurrentImportsNeverHoldMoreThanTheBudget) {
  constexpr uint64_t kCapacity = 1000;
  ImportBudget budget(kCapacity, 2s);
  std::atomic<uint64_t> busy{0};
  std::vector<std::thread> imports;
  for (int t = 0; t < 8; ++t) {
    imports.emplace_back([&, t] {
      for (int round = 0; round < 20; ++round) {
        try {
          ImportReservation held = budget.Reserve(100 + 37 * static_cast<uint64_t>(t));
          const ImportMemoryScope scope(held);
          for (int charge = 0; charge < 4; ++charge) ChargeImportMemory(40);
          std::this_thread::sleep_for(100us);
        } catch (const ImportBudgetBusyError&) {
          ++busy;
        }
      }
    });
  }
  for (std::thread& import : imports) import.join();
  const ImportBudgetStats stats = budget.Stats();
  EXPECT_EQ(stats.reservedBytes, 0u);
  EXPECT_LE(stats.peakReservedBytes, kCapacity);
  EXPECT_GT(stats.peakReservedBytes, kCapacity / 2);  // they did overlap
  EXPECT_EQ(stats.refusals, busy.load());
}

TEST(ImportBudgetTest, TheObserverSeesEveryChange) {
  ImportBudget budget(100);
  std::vector<uint64_t> seen;
  budget.SetObserver([&](const ImportBudgetStats& stats) { seen.push_back(stats.reservedBytes); });
  {
    ImportReservation held = budget.Reserve(30);
    held.Grow(5);
  }
  EXPECT_EQ(seen, (std::vector<uint64_t>{0, 30, 35, 0}));
}

}  // namespace
}  // namespace tcfarm
