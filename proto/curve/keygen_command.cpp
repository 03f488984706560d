#include "proto/curve/keygen_command.h"

#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

#include "proto/curve/curve_keys.h"

namespace tcfarm::curve {
namespace {

struct KeygenFlags {
  std::string directory = ".";
  std::string name;
  bool force = false;
};

// A name becomes a file name: no folders, nothing hidden.
void CheckName(const std::string& name) {
  if (name.empty() || name[0] == '.' || name.find('/') != std::string::npos) {
    throw std::invalid_argument("--name " + name + ": expected a plain file name, without '/' or a leading '.'");
  }
}

int RunKeygen(CLI::App& program, const KeygenFlags& flags) {
  try {
    CheckName(flags.name);
  } catch (const std::invalid_argument& e) {
    return cli::ReportUsageError(program, e.what());
  }
  try {
    const KeyPair keys = GenerateKeyPair();
    const auto [secretFile, publicFile] = WriteKeyPair(flags.directory, flags.name, keys, flags.force);
    std::printf("secret key: %s\npublic key: %s\n%s\n", secretFile.c_str(), publicFile.c_str(),
                keys.publicKey.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s keygen: %s\n", program.get_name().c_str(), e.what());
    return 1;
  }
}

}  // namespace

cli::Subcommand AddKeygenCommand(CLI::App& program) {
  CLI::App* keygen = program.add_subcommand(
      "keygen", "Make a CURVE key pair for the workers' ZeroMQ link: DIR/NAME.key (secret, mode 0600) "
                "and DIR/NAME.pub (public), for a coordinator or a worker alike");
  auto flags = std::make_shared<KeygenFlags>();
  keygen->add_option("--out", flags->directory, "Folder to write the two files in (made if missing)")
      ->type_name("DIR")
      ->capture_default_str();
  keygen->add_option("--name", flags->name, "The files' name: NAME.key and NAME.pub")
      ->type_name("NAME")
      ->required();
  keygen->add_flag("--force", flags->force, "Replace files that exist (otherwise they are kept and this fails)");
  return {keygen, [&program, flags]() { return RunKeygen(program, *flags); }};
}

}  // namespace tcfarm::curve
