// Thin RAII wrappers over the SQLite C API, for the job store. Every value reaches SQL
// through a bound parameter; SQL text is always a literal.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "coordinator/jobs/job_store.h"

namespace tcfarm {
namespace sqlite {

class Database {
 public:
  explicit Database(const std::filesystem::path& file) : path_(file.string()) {
    const int flags = SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX;
    const int rc = sqlite3_open_v2(path_.c_str(), &handle_, flags, nullptr);
    if (rc != SQLITE_OK) {
      // sqlite3_open_v2 allocates a handle even on failure, to carry the message.
      const std::string reason = handle_ ? sqlite3_errmsg(handle_) : sqlite3_errstr(rc);
      sqlite3_close(handle_);
      handle_ = nullptr;
      throw JobStoreError(path_ + ": cannot open job database: " + reason);
    }
    sqlite3_extended_result_codes(handle_, 1);
  }
  ~Database() {
    for (auto& [sql, idle] : idleStatements_) {
      for (sqlite3_stmt* statement : idle) sqlite3_finalize(statement);
    }
    sqlite3_close(handle_);  // every Statement has given its statement back by now (RAII)
  }
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  sqlite3* handle() const { return handle_; }
  const std::string& path() const { return path_; }

  [[noreturn]] void Throw(const std::string& context) const {
    ThrowFor(sqlite3_extended_errcode(handle_), context + ": " + sqlite3_errmsg(handle_));
  }

  // For statements without parameters or results (schema, pragmas, transaction control).
  void Exec(const char* sql) {
    char* message = nullptr;
    const int rc = sqlite3_exec(handle_, sql, nullptr, nullptr, &message);
    if (rc != SQLITE_OK) {
      const std::string reason = message ? message : sqlite3_errmsg(handle_);
      sqlite3_free(message);
      ThrowFor(rc, std::string(sql) + ": " + reason);
    }
  }

  // A prepared statement for `sql`: one used before and given back, or a new one. Each is
  // parsed once per connection, not per call: parsing was most of what recording a
  // frame cost.
  sqlite3_stmt* TakeStatement(const std::string& sql) {
    std::vector<sqlite3_stmt*>& idle = idleStatements_[sql];
    if (!idle.empty()) {
      sqlite3_stmt* statement = idle.back();
      idle.pop_back();
      return statement;
    }
    sqlite3_stmt* statement = nullptr;
    if (sqlite3_prepare_v3(handle_, sql.c_str(), -1, SQLITE_PREPARE_PERSISTENT, &statement, nullptr) != SQLITE_OK) {
      Throw("prepare " + sql);
    }
    return statement;
  }
  // Resets the statement and keeps it for the next TakeStatement of its SQL.
  void GiveBack(const std::string& sql, sqlite3_stmt* statement) {
    sqlite3_reset(statement);
    sqlite3_clear_bindings(statement);
    idleStatements_[sql].push_back(statement);
  }

  int Changes() const { return sqlite3_changes(handle_); }
  int64_t LastInsertRowId() const { return sqlite3_last_insert_rowid(handle_); }

 private:
  // A full disk (or a file at its size limit) and a failing one are told apart from
  // every other failure: the caller answers them with "no room" and retries later.
  [[noreturn]] void ThrowFor(int rc, const std::string& what) const {
    const int primary = rc & 0xff;
    if (primary == SQLITE_FULL || primary == SQLITE_IOERR) {
      throw JobStoreFullError(path_ + ": " + what +
                              " (the disk holding the job database is full or failing; nothing of this "
                              "write was kept)");
    }
    throw JobStoreError(path_ + ": " + what);
  }

  std::string path_;
  sqlite3* handle_ = nullptr;
  std::unordered_map<std::string, std::vector<sqlite3_stmt*>> idleStatements_;
};

class Statement {
 public:
  Statement(Database& db, std::string sql) : db_(db), sql_(std::move(sql)), handle_(db.TakeStatement(sql_)) {}
  ~Statement() { db_.GiveBack(sql_, handle_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  // Parameters are numbered from 1, as in SQLite.
  Statement& Bind(int index, int64_t value) {
    return Check(sqlite3_bind_int64(handle_, index, value));
  }
  Statement& Bind(int index, double value) {
    return Check(sqlite3_bind_double(handle_, index, value));
  }
  Statement& Bind(int index, std::string_view value) {
    return Check(sqlite3_bind_text(handle_, index, value.data(), static_cast<int>(value.size()),
                                   SQLITE_TRANSIENT));
  }

  // True while a row is ready; false when done.
  bool Step() {
    const int rc = sqlite3_step(handle_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    db_.Throw(std::string("step ") + sqlite3_sql(handle_));
  }
  void Run() {
    while (Step()) {
    }
  }
  // Ready to run again with new bindings.
  void Reset() { sqlite3_reset(handle_); }

  // Columns are numbered from 0, as in SQLite.
  int64_t Int64(int column) const { return sqlite3_column_int64(handle_, column); }
  bool IsNull(int column) const { return sqlite3_column_type(handle_, column) == SQLITE_NULL; }
  int Int(int column) const { return static_cast<int>(Int64(column)); }
  uint64_t UInt64(int column) const { return static_cast<uint64_t>(Int64(column)); }
  double Double(int column) const { return sqlite3_column_double(handle_, column); }
  std::string Text(int column) const {
    const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(handle_, column));
    return text ? std::string(text, sqlite3_column_bytes(handle_, column)) : std::string();
  }

 private:
  Statement& Check(int rc) {
    if (rc != SQLITE_OK) db_.Throw(std::string("bind ") + sqlite3_sql(handle_));
    return *this;
  }

  Database& db_;
  std::string sql_;
  sqlite3_stmt* handle_ = nullptr;
};

// kWrite (BEGIN IMMEDIATE) takes the write lock up front, so a read-then-write (claim,
// counters, merge-patch) cannot interleave with another connection's write; kRead gives
// several reads one consistent snapshot. Rolls back unless committed, so an exception
// leaves the file as it was.
class Transaction {
 public:
  enum class Mode { kRead, kWrite };
  explicit Transaction(Database& db, Mode mode = Mode::kWrite) : db_(db) {
    db_.Exec(mode == Mode::kWrite ? "BEGIN IMMEDIATE" : "BEGIN DEFERRED");
  }
  ~Transaction() {
    if (!committed_) sqlite3_exec(db_.handle(), "ROLLBACK", nullptr, nullptr, nullptr);
  }
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;

  void Commit() {
    db_.Exec("COMMIT");
    committed_ = true;
  }

 private:
  Database& db_;
  bool committed_ = false;
};

}  // namespace sqlite

}  // namespace tcfarm
