#include "retrace/map/sqlite.h"

#include "retrace/util/error.h"

namespace retrace {
namespace {

[[noreturn]] void ThrowSqlite(sqlite3* db, int code, const std::string& source) {
  throw InputError(source, DescribeSqliteError(code, db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(code)));
}

}  // namespace

std::string DescribeSqliteError(int code, const std::string& message) {
  const std::string text = PrintableText(message);
  switch (code & 0xFF) {  // the primary result code
    case SQLITE_NOTADB:
      return "not a retrace map (" + text + ")";
    case SQLITE_CORRUPT:
      return "corrupt map: " + text;
    default:
      return text;
  }
}

std::string PrintableText(const std::string& text, size_t max_length) {
  std::string result;
  for (const char c : text) {
    if (result.size() >= max_length) {
      result += "...";
      break;
    }
    const auto byte = static_cast<unsigned char>(c);
    if (c == '\n' || c == '\t' || c == '\r') {
      if (!result.empty() && result.back() != ' ') result += ' ';  // a line break separates words
    } else {
      result += (byte >= 0x20 && byte < 0x7f) ? c : '?';
    }
  }
  return result;
}

SqliteStatement::SqliteStatement(sqlite3* db, const std::string& sql, const std::string& source)
    : db_(db), source_(source) {
  const int code = sqlite3_prepare_v2(db_, sql.c_str(), -1, &statement_, nullptr);
  if (code != SQLITE_OK) ThrowSqlite(db_, code, source_);
}

SqliteStatement::~SqliteStatement() { sqlite3_finalize(statement_); }

SqliteStatement& SqliteStatement::Bind(int index, int64_t value) {
  sqlite3_bind_int64(statement_, index, value);
  return *this;
}

SqliteStatement& SqliteStatement::Bind(int index, double value) {
  sqlite3_bind_double(statement_, index, value);
  return *this;
}

SqliteStatement& SqliteStatement::Bind(int index, const std::string& value) {
  sqlite3_bind_text(statement_, index, value.data(), static_cast<int>(value.size()), SQLITE_TRANSIENT);
  return *this;
}

SqliteStatement& SqliteStatement::BindBlob(int index, const void* data, size_t size) {
  sqlite3_bind_blob(statement_, index, data, static_cast<int>(size), SQLITE_TRANSIENT);
  return *this;
}

SqliteStatement& SqliteStatement::BindNull(int index) {
  sqlite3_bind_null(statement_, index);
  return *this;
}

bool SqliteStatement::Step() {
  const int code = sqlite3_step(statement_);
  if (code == SQLITE_ROW) return true;
  if (code == SQLITE_DONE) return false;
  const std::string source = source_;
  sqlite3_reset(statement_);
  ThrowSqlite(db_, code, source);
}

void SqliteStatement::Reset() {
  sqlite3_reset(statement_);
  sqlite3_clear_bindings(statement_);
}

void SqliteStatement::Run() {
  Step();
  Reset();
}

int64_t SqliteStatement::ColumnInt(int index) const { return sqlite3_column_int64(statement_, index); }

double SqliteStatement::ColumnDouble(int index) const { return sqlite3_column_double(statement_, index); }

std::string SqliteStatement::ColumnText(int index) const {
  const auto* text = sqlite3_column_text(statement_, index);
  return text == nullptr ? std::string() : std::string(reinterpret_cast<const char*>(text));
}

std::vector<uint8_t> SqliteStatement::ColumnBlob(int index) const {
  const auto* data = static_cast<const uint8_t*>(sqlite3_column_blob(statement_, index));
  const int size = sqlite3_column_bytes(statement_, index);
  return data == nullptr ? std::vector<uint8_t>() : std::vector<uint8_t>(data, data + size);
}

bool SqliteStatement::ColumnIsNull(int index) const {
  return sqlite3_column_type(statement_, index) == SQLITE_NULL;
}

SqliteDatabase::SqliteDatabase(const std::filesystem::path& path, Mode mode) : source_(path.string()) {
  if (mode != Mode::kCreate && path != ":memory:") {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) throw InputError(source_, "no such map file");
    if (std::filesystem::is_directory(path, ec)) throw InputError(source_, "is a directory, not a map file");
  }
  int flags = SQLITE_OPEN_NOMUTEX;
  switch (mode) {
    case Mode::kReadOnly:
      flags |= SQLITE_OPEN_READONLY;
      break;
    case Mode::kReadWrite:
      flags |= SQLITE_OPEN_READWRITE;
      break;
    case Mode::kCreate:
      flags |= SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE;
      break;
  }
  const int code = sqlite3_open_v2(source_.c_str(), &db_, flags, nullptr);
  if (code != SQLITE_OK) {
    const std::string message = PrintableText(db_ != nullptr ? sqlite3_errmsg(db_) : sqlite3_errstr(code));
    sqlite3_close(db_);
    db_ = nullptr;
    throw InputError(source_, "cannot open map: " + message);
  }
  sqlite3_busy_timeout(db_, 5000);
}

SqliteDatabase::~SqliteDatabase() {
  statements_.clear();
  sqlite3_close(db_);
}

void SqliteDatabase::Execute(const std::string& sql) {
  char* error = nullptr;
  const int code = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error);
  if (code != SQLITE_OK) {
    const std::string message = DescribeSqliteError(code, error != nullptr ? error : sqlite3_errstr(code));
    sqlite3_free(error);
    throw InputError(source_, message);
  }
}

SqliteStatement& SqliteDatabase::Prepare(const std::string& sql) {
  auto& statement = statements_[sql];
  if (!statement) statement = std::make_unique<SqliteStatement>(db_, sql, source_);
  return *statement;
}

int64_t SqliteDatabase::PragmaInt(const std::string& name) {
  SqliteStatement statement(db_, "PRAGMA " + name + ";", source_);
  return statement.Step() ? statement.ColumnInt(0) : 0;
}

int64_t SqliteDatabase::LastInsertRowId() const { return sqlite3_last_insert_rowid(db_); }

SqliteTransaction::SqliteTransaction(SqliteDatabase* database) : database_(database) {
  database_->Execute("BEGIN IMMEDIATE;");
}

SqliteTransaction::~SqliteTransaction() {
  if (!done_) {
    try {
      database_->Execute("ROLLBACK;");
    } catch (...) {
      // Nothing sensible to do while unwinding; the database stays as it was before the transaction.
    }
  }
}

void SqliteTransaction::Commit() {
  database_->Execute("COMMIT;");
  done_ = true;
}

}  // namespace retrace
