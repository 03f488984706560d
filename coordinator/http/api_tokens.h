// The HTTP API's bearer tokens (`serve --api-tokens FILE`): who may read, submit or
// administer. The file holds one token a line with its role, in any of these forms:
//
//   # comments and blank lines are skipped
//   admin  8f2c...          ROLE TOKEN
//   8f2c...  read           TOKEN ROLE
//   submit:8f2c...          ROLE:TOKEN (or TOKEN:ROLE)
//
// The field that names a role is the role; the other is the token. Tokens are kept only as
// their SHA-256, looked up in constant time, and never printed: error messages name the
// file and line, and a job records only a token id (the first 12 hex characters of the
// token's SHA-256), which says which token submitted it without giving the token away.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tcfarm::http {

// Ordered: each role may do what the ones below it may.
enum class Role { kRead = 1, kSubmit = 2, kAdmin = 3 };

const char* RoleName(Role role);
std::optional<Role> RoleFromName(std::string_view name);

// Who sent a request with a known token.
struct Caller {
  Role role = Role::kRead;
  std::string tokenId;  // TokenId(token): safe to store and show
};

// The first 12 hex characters of the token's SHA-256.
std::string TokenId(std::string_view token);

// The token of an Authorization header value "Bearer TOKEN" (the scheme case-insensitive,
// RFC 6750), taken as it is: every byte after the spaces that follow the scheme, up to
// trailing spaces and tabs. Nullopt for another scheme or no token.
std::optional<std::string> BearerToken(std::string_view header);

class ApiTokens {
 public:
  // Shortest token taken without a warning: 16 characters of a random alphabet are beyond
  // guessing; a shorter one is more likely a password than a generated token.
  static constexpr size_t kMinTokenLength = 16;
  static constexpr size_t kMaxTokenLength = 512;

  // Reads the file; throws std::invalid_argument naming the file (and line) when it cannot
  // be read, has a bad line, repeats a token or holds none.
  static ApiTokens Load(const std::filesystem::path& file);
  // The same from text; `source` names it in errors.
  static ApiTokens Parse(std::string_view text, const std::string& source);

  // The caller a token belongs to, nullopt for an unknown one. Takes the same time whichever
  // token matches, or none: every entry is compared, by hash, without stopping early.
  std::optional<Caller> Find(std::string_view token) const;
  size_t size() const { return entries_.size(); }

 private:
  struct Entry {
    std::string sha256;  // hex of the token's SHA-256
    Role role;
  };
  std::vector<Entry> entries_;
};

}  // namespace tcfarm::http
