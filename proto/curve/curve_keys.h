// CurveZMQ keys (RFC 26) as tcfarm keeps them on disk, and the allow-list of worker keys.
//
// A key file is text: lines starting with '#' are comments, blank lines are ignored, and
// exactly one line holds the key as 40 Z85 characters (RFC 32). `NAME.key` holds a secret
// key (mode 0600), `NAME.pub` the public key derived from it. `keygen` writes both; the
// readers accept exactly what it writes.
#pragma once

#include <filesystem>
#include <map>
#include <string>

namespace tcfarm::curve {

// Z85 text of a 32-byte CURVE key.
inline constexpr size_t kKeyTextLength = 40;

struct KeyPair {
  std::string publicKey;  // Z85
  std::string secretKey;  // Z85
};

// A fresh key pair from libzmq (zmq_curve_keypair). Throws std::runtime_error when libzmq
// was built without CURVE.
KeyPair GenerateKeyPair();
// The public key of a secret key (zmq_curve_public). Throws std::invalid_argument for
// text that is not a Z85 key.
std::string PublicKeyOf(const std::string& secretKey);
bool IsKeyText(const std::string& text);

// The key a key file holds. Throws std::invalid_argument naming the file, the line and
// what was expected.
std::string ReadKeyFile(const std::filesystem::path& file);
// A secret key file and its public key (PublicKeyOf), ready to use.
KeyPair ReadSecretKeyFile(const std::filesystem::path& file);

// Writes DIR/NAME.key (mode 0600, created so, never readable by others) and DIR/NAME.pub.
// Refuses (std::runtime_error) to overwrite an existing file unless overwrite is set.
// Returns the paths written: {secret, public}.
std::pair<std::filesystem::path, std::filesystem::path> WriteKeyPair(
    const std::filesystem::path& directory, const std::string& name, const KeyPair& keys,
    bool overwrite = false);

// Every `*.pub` file of a folder: public key -> file name. A file that is not a key file
// is left out and reported through `skipped` (file: why), so that one bad file does not
// lock every worker out. Throws std::invalid_argument when the folder cannot be listed.
std::map<std::string, std::string> ReadPublicKeys(const std::filesystem::path& directory,
                                                  std::map<std::string, std::string>* skipped = nullptr);

}  // namespace tcfarm::curve
