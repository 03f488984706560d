#include "coordinator/http/api_tokens.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>

#include "proto/wire/content_hash.h"

namespace tcfarm::http {
namespace {

constexpr const char* kExpectedForms = "expected ROLE TOKEN, TOKEN ROLE, ROLE:TOKEN or TOKEN:ROLE";
constexpr size_t kTokenIdLength = 12;

std::string Lowercase(std::string_view text) {
  std::string lower(text);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return lower;
}

// RFC 6750's b64token: what may follow "Bearer " in a header without quoting. It has no
// ':', '#' or space, so the line forms below can never cut a token apart.
bool IsBearerTokenText(std::string_view token) {
  const size_t padding = std::min(token.find('='), token.size());
  if (padding == 0) return false;
  const std::string_view body = token.substr(0, padding);
  return std::all_of(body.begin(), body.end(),
                     [](unsigned char c) {
                       return std::isalnum(c) || c == '-' || c == '.' || c == '_' || c == '~' || c == '+' ||
                              c == '/';
                     }) &&
         token.find_first_not_of('=', padding) == std::string_view::npos;
}

std::vector<std::string> SplitFields(std::string_view line) {
  std::istringstream words{std::string(line)};
  std::vector<std::string> fields;
  for (std::string field; words >> field;) fields.push_back(field);
  if (fields.size() == 1) {
    const size_t colon = fields[0].find(':');
    if (colon != std::string::npos) {
      const std::string joined = fields[0];
      fields = {joined.substr(0, colon), joined.substr(colon + 1)};
    }
  }
  return fields;
}

struct ParsedLine {
  std::string token;
  Role role;
};

// One line without its comment; the messages never quote the token.
ParsedLine ParseLine(std::string_view line) {
  const std::vector<std::string> fields = SplitFields(line);
  if (fields.size() != 2) {
    throw std::invalid_argument("has " + std::to_string(fields.size()) + " field(s); " + kExpectedForms);
  }
  const std::optional<Role> first = RoleFromName(fields[0]);
  const std::optional<Role> second = RoleFromName(fields[1]);
  if (first && second) throw std::invalid_argument("both fields name a role; expected one role and one token");
  if (!first && !second) {
    throw std::invalid_argument("neither field is a role; expected one of read, submit, admin beside the token");
  }
  ParsedLine parsed{first ? fields[1] : fields[0], first ? *first : *second};
  if (parsed.token.size() > ApiTokens::kMaxTokenLength) {
    throw std::invalid_argument("the token is " + std::to_string(parsed.token.size()) +
                                " characters long; expected at most " + std::to_string(ApiTokens::kMaxTokenLength) +
                                " (make one with: openssl rand -hex 32)");
  }
  if (!IsBearerTokenText(parsed.token)) {
    throw std::invalid_argument(
        "the token holds a character a bearer token may not; expected letters, digits and - . _ ~ + / "
        "(then = padding), e.g. from: openssl rand -hex 32");
  }
  return parsed;
}

}  // namespace

const char* RoleName(Role role) {
  switch (role) {
    case Role::kRead: return "read";
    case Role::kSubmit: return "submit";
    case Role::kAdmin: return "admin";
  }
  return "?";
}

std::optional<Role> RoleFromName(std::string_view name) {
  const std::string lower = Lowercase(name);
  for (Role role : {Role::kRead, Role::kSubmit, Role::kAdmin}) {
    if (lower == RoleName(role)) return role;
  }
  return std::nullopt;
}

std::optional<std::string> BearerToken(std::string_view header) {
  constexpr std::string_view kScheme = "bearer";
  if (header.size() <= kScheme.size() || header[kScheme.size()] != ' ') return std::nullopt;
  if (Lowercase(header.substr(0, kScheme.size())) != kScheme) return std::nullopt;
  const size_t begin = header.find_first_not_of(' ', kScheme.size());
  const size_t end = header.find_last_not_of(" \t");
  if (begin == std::string_view::npos) return std::nullopt;
  return std::string(header.substr(begin, end - begin + 1));
}

std::string TokenId(std::string_view token) { return wire::Sha256Hex(token).substr(0, kTokenIdLength); }

ApiTokens ApiTokens::Load(const std::filesystem::path& file) {
  std::error_code error;
  std::ifstream in(file, std::ios::binary);
  if (!in || std::filesystem::is_directory(file, error)) {
    throw std::invalid_argument(file.string() + ": cannot read it; expected a file of API tokens, one a line");
  }
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return Parse(text, file.string());
}

ApiTokens ApiTokens::Parse(std::string_view text, const std::string& source) {
  ApiTokens tokens;
  std::vector<size_t> lineOfEntry;
  std::istringstream lines{std::string(text)};
  size_t lineNumber = 0;
  for (std::string line; std::getline(lines, line);) {
    ++lineNumber;
    line = line.substr(0, line.find('#'));  // a token never holds '#'
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const std::string where = source + " line " + std::to_string(lineNumber) + ": ";
    ParsedLine parsed{"", Role::kRead};
    try {
      parsed = ParseLine(line);
    } catch (const std::invalid_argument& error) {
      throw std::invalid_argument(where + error.what());
    }
    // A short token is allowed (the farm's owner chose it) but said to be weak.
    if (parsed.token.size() < kMinTokenLength) {
      std::fprintf(stderr, "warning: %sthe token is %zu characters long, easy to guess; %zu or more are safe "
                   "(make one with: openssl rand -hex 32)\n", where.c_str(), parsed.token.size(), kMinTokenLength);
    }
    Entry entry{wire::Sha256Hex(parsed.token), parsed.role};
    for (size_t i = 0; i < tokens.entries_.size(); ++i) {
      if (tokens.entries_[i].sha256 == entry.sha256) {
        throw std::invalid_argument(where + "repeats the token of line " + std::to_string(lineOfEntry[i]) +
                                    "; expected each token once, with one role");
      }
    }
    tokens.entries_.push_back(std::move(entry));
    lineOfEntry.push_back(lineNumber);
  }
  if (tokens.entries_.empty()) {
    throw std::invalid_argument(source + " holds no token; expected lines like 'admin TOKEN' or 'TOKEN read'");
  }
  return tokens;
}

std::optional<Caller> ApiTokens::Find(std::string_view token) const {
  // Comparing hashes, not tokens: how long a comparison takes says nothing about the
  // token's characters, and every entry is compared whatever matched before it.
  const std::string presented = wire::Sha256Hex(token);
  const Entry* match = nullptr;
  for (const Entry& entry : entries_) {
    unsigned char difference = 0;
    for (size_t i = 0; i < presented.size(); ++i) {
      difference |= static_cast<unsigned char>(presented[i] ^ entry.sha256[i]);
    }
    if (difference == 0) match = &entry;
  }
  if (match == nullptr) return std::nullopt;
  return Caller{match->role, presented.substr(0, kTokenIdLength)};
}

}  // namespace tcfarm::http
