#pragma once

// A thin RAII layer over the SQLite C API: a connection, cached prepared statements and transactions.
// Every SQLite error becomes retrace::InputError naming the database file, so a corrupt or foreign file gives a
// one-line message instead of a crash. SQLite's messages can quote the file's own bytes (a corrupt schema): they are
// reduced to printable ASCII first.

#include <sqlite3.h>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

namespace retrace {

// `text` with line breaks and tabs turned into spaces and every other byte outside printable ASCII (control
// characters, non-ASCII) replaced by '?', cut after `max_length` characters: fit to quote untrusted bytes in a
// one-line error message.
std::string PrintableText(const std::string& text, size_t max_length = 200);

// The one-line message of an SQLite error: printable, and saying "not a retrace map" for a foreign file and
// "corrupt map" for a damaged one.
std::string DescribeSqliteError(int code, const std::string& message);

class SqliteStatement {
 public:
  SqliteStatement(sqlite3* db, const std::string& sql, const std::string& source);
  ~SqliteStatement();
  SqliteStatement(const SqliteStatement&) = delete;
  SqliteStatement& operator=(const SqliteStatement&) = delete;

  // Binding, 1-based like SQLite.
  SqliteStatement& Bind(int index, int64_t value);
  SqliteStatement& Bind(int index, double value);
  SqliteStatement& Bind(int index, const std::string& value);
  SqliteStatement& BindBlob(int index, const void* data, size_t size);
  SqliteStatement& BindNull(int index);

  // Steps once: true when a row is available, false when done.
  bool Step();
  // Resets the statement and clears its bindings so it can be run again.
  void Reset();
  // Runs a statement that returns no rows, then resets it.
  void Run();

  int64_t ColumnInt(int index) const;
  double ColumnDouble(int index) const;
  std::string ColumnText(int index) const;
  std::vector<uint8_t> ColumnBlob(int index) const;
  bool ColumnIsNull(int index) const;

 private:
  sqlite3* db_;
  sqlite3_stmt* statement_ = nullptr;
  std::string source_;
};

class SqliteDatabase {
 public:
  enum class Mode { kReadOnly, kReadWrite, kCreate };

  SqliteDatabase(const std::filesystem::path& path, Mode mode);
  ~SqliteDatabase();
  SqliteDatabase(const SqliteDatabase&) = delete;
  SqliteDatabase& operator=(const SqliteDatabase&) = delete;

  // Runs one or more SQL statements without results.
  void Execute(const std::string& sql);
  // A prepared statement cached by its SQL text; valid while the database lives.
  SqliteStatement& Prepare(const std::string& sql);
  int64_t PragmaInt(const std::string& name);
  int64_t LastInsertRowId() const;

  const std::string& source() const { return source_; }
  sqlite3* handle() { return db_; }

 private:
  sqlite3* db_ = nullptr;
  std::string source_;
  std::unordered_map<std::string, std::unique_ptr<SqliteStatement>> statements_;
};

// RAII transaction: commits when Commit() is called, rolls back otherwise (e.g. on an exception).
class SqliteTransaction {
 public:
  explicit SqliteTransaction(SqliteDatabase* database);
  ~SqliteTransaction();
  void Commit();

 private:
  SqliteDatabase* database_;
  bool done_ = false;
};

}  // namespace retrace
