#include "proto/curve/curve_keys.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <zmq.h>

namespace tcfarm::curve {
namespace {

// Key files are a few lines; anything longer is not one.
constexpr std::uintmax_t kMaxKeyFileBytes = 4096;

// Z85's alphabet (RFC 32).
bool IsZ85Character(char c) {
  static const std::string alphabet =
      "0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ.-:+=^!/*?&<>()[]{}@%$#";
  return alphabet.find(c) != std::string::npos;
}

std::string Trimmed(const std::string& line) {
  const size_t begin = line.find_first_not_of(" \t\r");
  if (begin == std::string::npos) return "";
  return line.substr(begin, line.find_last_not_of(" \t\r") - begin + 1);
}

std::string ReadSmallFile(const std::filesystem::path& file) {
  std::error_code ec;
  const std::uintmax_t size = std::filesystem::file_size(file, ec);
  if (ec) throw std::invalid_argument(file.string() + ": cannot read: " + ec.message());
  if (size > kMaxKeyFileBytes) {
    throw std::invalid_argument(file.string() + ": " + std::to_string(size) +
                                " bytes; a key file is a few lines");
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::invalid_argument(file.string() + ": cannot open: " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Writes text to a new file with the given mode (O_EXCL unless overwriting, so a secret
// is never written into a file someone else made readable).
void WriteFileWithMode(const std::filesystem::path& file, const std::string& text, mode_t mode,
                       bool overwrite) {
  if (overwrite) ::unlink(file.c_str());
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, mode);
  if (fd < 0) {
    throw std::runtime_error(file.string() + ": cannot create: " + std::strerror(errno) +
                             (errno == EEXIST ? " (give --force to replace it)" : ""));
  }
  ::fchmod(fd, mode);  // whatever the umask
  const ssize_t written = ::write(fd, text.data(), text.size());
  const bool closed = ::close(fd) == 0;
  if (written != static_cast<ssize_t>(text.size()) || !closed) {
    throw std::runtime_error(file.string() + ": cannot write: " + std::strerror(errno));
  }
}

}  // namespace

bool IsKeyText(const std::string& text) {
  if (text.size() != kKeyTextLength) return false;
  for (char c : text) {
    if (!IsZ85Character(c)) return false;
  }
  return true;
}

KeyPair GenerateKeyPair() {
  char publicKey[kKeyTextLength + 1] = {};
  char secretKey[kKeyTextLength + 1] = {};
  if (zmq_curve_keypair(publicKey, secretKey) != 0) {
    throw std::runtime_error(std::string("cannot make a CURVE key pair: ") + zmq_strerror(zmq_errno()) +
                             " (is libzmq built with CURVE?)");
  }
  return {publicKey, secretKey};
}

std::string PublicKeyOf(const std::string& secretKey) {
  if (!IsKeyText(secretKey)) {
    throw std::invalid_argument("not a CURVE key: expected 40 Z85 characters");
  }
  char publicKey[kKeyTextLength + 1] = {};
  if (zmq_curve_public(publicKey, secretKey.c_str()) != 0) {
    throw std::invalid_argument(std::string("cannot derive the public key: ") + zmq_strerror(zmq_errno()));
  }
  return publicKey;
}

std::string ReadKeyFile(const std::filesystem::path& file) {
  std::istringstream lines(ReadSmallFile(file));
  std::string line, key;
  for (int number = 1; std::getline(lines, line); ++number) {
    const std::string text = Trimmed(line);
    if (text.empty() || text[0] == '#') continue;
    const std::string where = file.string() + " line " + std::to_string(number);
    if (!key.empty()) throw std::invalid_argument(where + ": a second key; expected exactly one");
    if (!IsKeyText(text)) {
      throw std::invalid_argument(where + ": expected a CURVE key, 40 Z85 characters (as keygen writes), got " +
                                  std::to_string(text.size()) + " characters");
    }
    key = text;
  }
  if (key.empty()) throw std::invalid_argument(file.string() + ": no key in it; expected 40 Z85 characters");
  return key;
}

KeyPair ReadSecretKeyFile(const std::filesystem::path& file) {
  KeyPair keys;
  keys.secretKey = ReadKeyFile(file);
  try {
    keys.publicKey = PublicKeyOf(keys.secretKey);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(file.string() + ": " + e.what());
  }
  return keys;
}

std::pair<std::filesystem::path, std::filesystem::path> WriteKeyPair(
    const std::filesystem::path& directory, const std::string& name, const KeyPair& keys, bool overwrite) {
  std::filesystem::create_directories(directory);
  const std::filesystem::path secretFile = directory / (name + ".key");
  const std::filesystem::path publicFile = directory / (name + ".pub");
  WriteFileWithMode(secretFile,
                    "# tcfarm CURVE secret key \"" + name + "\": keep it private (mode 0600)\n" +
                        keys.secretKey + "\n",
                    0600, overwrite);
  WriteFileWithMode(publicFile, "# tcfarm CURVE public key \"" + name + "\"\n" + keys.publicKey + "\n",
                    0644, overwrite);
  return {secretFile, publicFile};
}

std::map<std::string, std::string> ReadPublicKeys(const std::filesystem::path& directory,
                                                  std::map<std::string, std::string>* skipped) {
  std::error_code ec;
  std::filesystem::directory_iterator entries(directory, ec);
  if (ec) throw std::invalid_argument(directory.string() + ": cannot list: " + ec.message());
  std::map<std::string, std::string> keys;
  for (const auto& entry : entries) {
    if (entry.path().extension() != ".pub") continue;
    try {
      keys[ReadKeyFile(entry.path())] = entry.path().filename().string();
    } catch (const std::invalid_argument& e) {
      if (skipped) (*skipped)[entry.path().string()] = e.what();
    }
  }
  return keys;
}

}  // namespace tcfarm::curve
