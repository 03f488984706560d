// One memory budget for every scene a process imports at once. The per-file limits of the
// importers (scene_limits.h, the glTF reader's value budget) bound what one file may
// decode; they do not bound eight such files imported side by side. The coordinator's
// imports (its HTTP API's scene checks and submits, its referee's scenes) share one
// ImportBudget: each import holds an ImportReservation that grows, before anything is
// allocated, by what the importers are about to decode (file copies, JSON documents,
// meshopt and Draco geometry, accessor values, texture pixels). A reservation that does
// not fit waits a short, bounded time for others to end, then fails with
// ImportBudgetBusyError (the HTTP API's 503 with Retry-After); one that could never fit,
// even alone, fails at once with ImportTooLargeError.
//
// Imports are served oldest first, and an import that already holds part of the budget
// never waits beside an older one: it fails at once instead (wait-die), giving its part
// back. Two imports each holding half the budget and each waiting for the other's half
// would otherwise both wait out the bound and both fail.
//
// The importers do not take the budget as an argument: an ImportMemoryScope makes a
// reservation the one this thread's imports charge (ChargeImportMemory), nested imports (a
// tcfarm scene importing a glTF file) included. Without a scope, as in the workers and the
// command-line tools, charging does nothing.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>

namespace tcfarm {

// The budget is in use by other imports: the same import may fit after retryAfter.
class ImportBudgetBusyError : public std::runtime_error {
 public:
  ImportBudgetBusyError(const std::string& message, std::chrono::seconds retryAfter)
      : std::runtime_error(message), retryAfter_(retryAfter) {}
  std::chrono::seconds retryAfter() const { return retryAfter_; }

 private:
  std::chrono::seconds retryAfter_;
};

// One import alone would need more than the whole budget: no retry can help.
class ImportTooLargeError : public std::runtime_error {
 public:
  explicit ImportTooLargeError(const std::string& message) : std::runtime_error(message) {}
};

class ImportBudget;
class ImportReservation;
ImportReservation ReserveImportMemory(uint64_t bytes);

// Bytes held from an ImportBudget, given back when it is destroyed. Movable, not copyable.
class ImportReservation {
 public:
  ImportReservation() = default;  // holds nothing, of no budget
  ~ImportReservation() { Release(); }
  ImportReservation(ImportReservation&& other) noexcept
      : budget_(std::exchange(other.budget_, nullptr)),
        ticket_(other.ticket_),
        bytes_(std::exchange(other.bytes_, 0)) {}
  ImportReservation& operator=(ImportReservation&& other) noexcept;
  ImportReservation(const ImportReservation&) = delete;
  ImportReservation& operator=(const ImportReservation&) = delete;

  // Holds `bytes` more, waiting as ImportBudget::Reserve does. Throws as Reserve does,
  // still holding what it held. Without a budget, does nothing.
  void Grow(uint64_t bytes);
  uint64_t bytes() const { return bytes_; }

 private:
  friend class ImportBudget;
  friend ImportReservation ReserveImportMemory(uint64_t bytes);
  ImportReservation(ImportBudget* budget, uint64_t ticket, uint64_t bytes)
      : budget_(budget), ticket_(ticket), bytes_(bytes) {}
  void Release();

  ImportBudget* budget_ = nullptr;
  uint64_t ticket_ = 0;  // the import's age: lower is older
  uint64_t bytes_ = 0;
};

struct ImportBudgetStats {
  uint64_t capacityBytes = 0;
  uint64_t reservedBytes = 0;      // held now
  uint64_t peakReservedBytes = 0;  // the most ever held at once
  uint64_t waits = 0;              // reservations not granted at once
  uint64_t refusals = 0;           // ImportBudgetBusyError thrown
};

class ImportBudget {
 public:
  // How long a reservation waits for room before ImportBudgetBusyError: long enough for a
  // scene check to end, short enough for an HTTP client not to time out.
  static constexpr std::chrono::milliseconds kDefaultWait{2000};

  explicit ImportBudget(uint64_t capacityBytes, std::chrono::milliseconds maxWait = kDefaultWait);
  ~ImportBudget();  // every reservation must have been given back
  ImportBudget(const ImportBudget&) = delete;
  ImportBudget& operator=(const ImportBudget&) = delete;

  // A new import, holding `bytes` until the reservation is destroyed. Waits up to maxWait
  // while other reservations leave too little, or an older import waits; throws
  // ImportBudgetBusyError when they still do, and ImportTooLargeError at once when `bytes`
  // exceed the capacity.
  ImportReservation Reserve(uint64_t bytes);

  ImportBudgetStats Stats() const;
  uint64_t capacityBytes() const { return capacity_; }
  // The client's Retry-After after ImportBudgetBusyError: the wait, in whole seconds, at least 1.
  std::chrono::seconds RetryAfter() const;
  // Called with the stats after every change, under the budget's lock (a gauge's Set): it
  // must be quick and must not reserve.
  void SetObserver(std::function<void(const ImportBudgetStats&)> observer);

 private:
  friend class ImportReservation;
  friend ImportReservation ReserveImportMemory(uint64_t bytes);
  // Adds `bytes` for the import `ticket`, which holds `held` already.
  void Take(uint64_t ticket, uint64_t held, uint64_t bytes);
  // Under mutex_: waits until `bytes` fit and no older import waits; false when the wait
  // ran out, or at once when the import holds memory and an older one waits.
  bool AwaitTurn(std::unique_lock<std::mutex>& lock, uint64_t ticket, uint64_t held, uint64_t bytes);
  void Give(uint64_t bytes);
  void Notify();  // under mutex_

  const uint64_t capacity_;
  const std::chrono::milliseconds maxWait_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;  // memory given back, or an import began or ended waiting
  uint64_t nextTicket_ = 0;
  std::set<uint64_t> waiting_;  // the tickets of the imports waiting now
  ImportBudgetStats stats_;
  std::function<void(const ImportBudgetStats&)> observer_;
};

// While it lives, the imports this thread runs charge `reservation` (ChargeImportMemory).
// Scopes nest: the one it replaced is restored when it ends.
class ImportMemoryScope {
 public:
  explicit ImportMemoryScope(ImportReservation& reservation);
  ~ImportMemoryScope();
  ImportMemoryScope(const ImportMemoryScope&) = delete;
  ImportMemoryScope& operator=(const ImportMemoryScope&) = delete;

 private:
  ImportReservation* replaced_;
};

// Called by the importers before they allocate `bytes` that may live until the import
// ends: grows the reservation of this thread's ImportMemoryScope. Throws
// ImportBudgetBusyError or ImportTooLargeError; without a scope, does nothing.
void ChargeImportMemory(uint64_t bytes);
// True inside an ImportMemoryScope: a charge whose amount takes work to know (a pass over a
// large text) is worked out only then.
bool ChargingImportMemory();

// ChargeImportMemory for memory the import frees again before it ends (a Draco mesh, a
// texture decoded to be checked): held from the same budget only while the returned
// reservation lives, so that a scene's hundred textures do not add up. Without a scope,
// an empty reservation.
ImportReservation ReserveImportMemory(uint64_t bytes);

// Runs `work` (an import: ImportScene, ParseScene, a texture decode) within `budget`: it
// reserves `upfrontBytes` first (what the work holds before it charges anything itself,
// such as the text it is given), and everything the work charges is held with them until
// it returns. Without a budget, just runs `work`. Throws as ImportBudget::Reserve does.
template <typename Work>
auto WithinImportBudget(ImportBudget* budget, uint64_t upfrontBytes, Work&& work) -> decltype(work()) {
  if (budget == nullptr) return work();
  ImportReservation reservation = budget->Reserve(upfrontBytes);
  const ImportMemoryScope scope(reservation);
  return work();
}

}  // namespace tcfarm
