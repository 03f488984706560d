#include "proto/command_line/command_line.h"

#include <cstdio>
#include <stdexcept>
#include <vector>

namespace tcfarm::cli {
namespace {

// CLI11's 30 characters put "--zmq ENDPOINT=tcp://*:5555" against its description.
constexpr size_t kFlagColumnWidth = 36;

// "tcfarm-coordinator serve": the program and the subcommands given so far, so a complaint
// says whose flags it is about.
std::string CommandPath(const CLI::App& app) {
  std::string path = app.get_name();
  for (const CLI::App* command = &app;;) {
    const std::vector<CLI::App*> given = command->get_subcommands();
    if (given.empty()) return path;
    command = given.front();
    path += " " + command->get_name();
  }
}

// CLI11 says "--threads: 1 required N missing" for a flag given without its value.
std::string Reworded(const CLI::ParseError& error) {
  std::string message = error.what();
  if (dynamic_cast<const CLI::ArgumentMismatch*>(&error) != nullptr) {
    const size_t required = message.find(": 1 required ");
    const std::string missing = " missing";
    if (required != std::string::npos && message.size() > missing.size() &&
        message.compare(message.size() - missing.size(), missing.size(), missing) == 0) {
      const size_t typeAt = required + std::string(": 1 required ").size();
      return message.substr(0, required) + " needs a value: " +
             message.substr(typeAt, message.size() - missing.size() - typeAt);
    }
  }
  return message;
}

// CLI11 takes an unknown command word for a stray argument and then complains that "A
// subcommand is required"; naming the word, or the commands there are, is clearer.
std::string UnknownCommand(const CLI::App& app, int argc, const char* const* argv) {
  std::vector<const CLI::App*> commands = app.get_subcommands([](const CLI::App*) { return true; });
  if (commands.empty() || (argc >= 2 && argv[1][0] == '-')) return "";
  std::string known;
  for (const CLI::App* command : commands) {
    if (argc >= 2 && command->check_name(argv[1])) return "";
    known += (known.empty() ? "" : ", ") + command->get_name();
  }
  if (argc < 2) return "no command given; expected one of " + known;
  return std::string("unknown command '") + argv[1] + "'; expected one of " + known;
}

}  // namespace

CLI::Validator IntegerFrom(long long minimum, long long maximum) {
  const std::string expected =
      "expected an integer from " + std::to_string(minimum) + " to " + std::to_string(maximum);
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        size_t used = 0;
        long long value = 0;
        try {
          value = std::stoll(text, &used, 10);
        } catch (const std::exception&) {
          used = 0;
        }
        if (text.empty() || used != text.size() || value < minimum || value > maximum) {
          return expected + ", not '" + text + "'";
        }
        text = std::to_string(value);
        return "";
      },
      "");
}

void SetUpProgram(CLI::App& program) {
  program.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
  program.get_formatter()->column_width(kFlagColumnWidth);
}

std::optional<int> ParseCommandLine(CLI::App& app, int argc, const char* const* argv) {
  if (std::string unknown = UnknownCommand(app, argc, argv); !unknown.empty()) {
    return ReportUsageError(app, unknown);
  }
  try {
    app.parse(argc, argv);
    return std::nullopt;
  } catch (const CLI::ParseError& error) {
    // --help (and the like) arrive as exceptions too: CLI11 prints those itself.
    if (error.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(error);
    return ReportUsageError(app, Reworded(error));
  }
}

int ReportUsageError(const CLI::App& app, const std::string& message) {
  const std::string command = CommandPath(app);
  std::fprintf(stderr, "%s: %s\nRun '%s --help' for usage.\n", command.c_str(), message.c_str(),
               command.c_str());
  return kUsageError;
}

}  // namespace tcfarm::cli
