#include "proto/scene/import/import_budget.h"

#include <algorithm>
#include <cstdio>

namespace tcfarm {
namespace {

// The reservation this thread's imports charge (ImportMemoryScope), if any.
thread_local ImportReservation* currentReservation = nullptr;

// "512 bytes", "3.5 MiB": how messages show an amount.
std::string Amount(uint64_t bytes) {
  if (bytes < (1 << 20)) return std::to_string(bytes) + " bytes";
  char text[32];
  std::snprintf(text, sizeof text, "%.1f MiB", static_cast<double>(bytes) / (1 << 20));
  return text;
}

}  // namespace

ImportReservation& ImportReservation::operator=(ImportReservation&& other) noexcept {
  if (this != &other) {
    Release();
    budget_ = std::exchange(other.budget_, nullptr);
    ticket_ = other.ticket_;
    bytes_ = std::exchange(other.bytes_, 0);
  }
  return *this;
}

void ImportReservation::Grow(uint64_t bytes) {
  if (budget_ == nullptr || bytes == 0) return;
  budget_->Take(ticket_, bytes_, bytes);
  bytes_ += bytes;
}

void ImportReservation::Release() {
  if (budget_ != nullptr && bytes_ > 0) budget_->Give(bytes_);
  budget_ = nullptr;
  bytes_ = 0;
}

ImportBudget::ImportBudget(uint64_t capacityBytes, std::chrono::milliseconds maxWait)
    : capacity_(capacityBytes), maxWait_(maxWait) {
  stats_.capacityBytes = capacityBytes;
}

ImportBudget::~ImportBudget() {
  if (stats_.reservedBytes != 0) {
    std::fprintf(stderr, "ImportBudget destroyed with %llu bytes still reserved\n",
                 static_cast<unsigned long long>(stats_.reservedBytes));
  }
}

ImportReservation ImportBudget::Reserve(uint64_t bytes) {
  uint64_t ticket = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ticket = nextTicket_++;
  }
  Take(ticket, 0, bytes);
  return ImportReservation(this, ticket, bytes);
}

void ImportBudget::Take(uint64_t ticket, uint64_t held, uint64_t bytes) {
  // Refused before waiting: no other import's end can make room for more than everything.
  if (bytes > capacity_ || held > capacity_ - bytes) {
    throw ImportTooLargeError("the import needs " + Amount(held + bytes) +
                              " of memory, more than the import budget of " + Amount(capacity_) +
                              " holds for all imports together");
  }
  std::unique_lock<std::mutex> lock(mutex_);
  if (!AwaitTurn(lock, ticket, held, bytes)) {
    ++stats_.refusals;
    const uint64_t reserved = stats_.reservedBytes;
    Notify();
    throw ImportBudgetBusyError("the import needs " + Amount(bytes) + " more of the import budget, and imports running "
                                    "now hold " + Amount(reserved) + " of its " + Amount(capacity_),
                                RetryAfter());
  }
  stats_.reservedBytes += bytes;
  stats_.peakReservedBytes = std::max(stats_.peakReservedBytes, stats_.reservedBytes);
  Notify();
}

bool ImportBudget::AwaitTurn(std::unique_lock<std::mutex>& lock, uint64_t ticket, uint64_t held, uint64_t bytes) {
  const auto olderWaits = [&] { return !waiting_.empty() && *waiting_.begin() < ticket; };
  const auto granted = [&] { return stats_.reservedBytes <= capacity_ - bytes && !olderWaits(); };
  if (granted()) return true;
  ++stats_.waits;
  waiting_.insert(ticket);
  changed_.notify_all();  // a younger import waiting with memory held gives way now
  const bool gotTurn = changed_.wait_for(lock, maxWait_, [&] { return granted() || (held > 0 && olderWaits()); }) &&
                       granted();
  waiting_.erase(ticket);
  changed_.notify_all();  // younger imports may go now
  return gotTurn;
}

void ImportBudget::Give(uint64_t bytes) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stats_.reservedBytes -= std::min(bytes, stats_.reservedBytes);
    Notify();
  }
  changed_.notify_all();
}

void ImportBudget::Notify() {
  if (observer_) observer_(stats_);
}

ImportBudgetStats ImportBudget::Stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

std::chrono::seconds ImportBudget::RetryAfter() const {
  const auto seconds = std::chrono::ceil<std::chrono::seconds>(maxWait_);
  return std::max(seconds, std::chrono::seconds(1));
}

void ImportBudget::SetObserver(std::function<void(const ImportBudgetStats&)> observer) {
  std::lock_guard<std::mutex> lock(mutex_);
  observer_ = std::move(observer);
  Notify();
}

ImportMemoryScope::ImportMemoryScope(ImportReservation& reservation) : replaced_(currentReservation) {
  currentReservation = &reservation;
}

ImportMemoryScope::~ImportMemoryScope() { currentReservation = replaced_; }

void ChargeImportMemory(uint64_t bytes) {
  if (currentReservation != nullptr) currentReservation->Grow(bytes);
}

bool ChargingImportMemory() { return currentReservation != nullptr; }

ImportReservation ReserveImportMemory(uint64_t bytes) {
  ImportBudget* budget = currentReservation != nullptr ? currentReservation->budget_ : nullptr;
  if (budget == nullptr) return ImportReservation();
  // Too large counts what the import holds already: it would otherwise wait for itself.
  budget->Take(currentReservation->ticket_, currentReservation->bytes_, bytes);
  return ImportReservation(budget, currentReservation->ticket_, bytes);
}

}  // namespace tcfarm
