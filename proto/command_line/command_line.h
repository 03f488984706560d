// The command lines of every tcfarm program, on CLI11, so that they all behave alike:
// integers are checked the same way, --help prints on stdout and exits 0, and a bad flag
// or value gets one line on stderr naming it and exit code 2 (a usage error).
#pragma once

#include <CLI/CLI.hpp>

#include <functional>
#include <optional>
#include <string>

namespace tcfarm::cli {

// A subcommand, and what runs it once the command line has parsed (returns the exit code).
struct Subcommand {
  CLI::App* app;
  std::function<int()> run;
};

// Exit code for a command line that cannot be run: a bad flag, a bad value, a missing one.
inline constexpr int kUsageError = 2;

// A decimal integer from minimum to maximum. It is handed on in plain decimal, since
// CLI11's own conversion would read "010" as octal.
CLI::Validator IntegerFrom(long long minimum, long long maximum);

// For a program's top-level app, before its options and commands are added: an option given
// twice keeps its last value, as the hand-written parsers did, and the help's flag column
// is wide enough for a flag, its value and its default.
void SetUpProgram(CLI::App& program);

// Parses argv into app. Returns nothing when the program should go on; otherwise the exit
// code, with the help (0) or the complaint (kUsageError) printed.
std::optional<int> ParseCommandLine(CLI::App& app, int argc, const char* const* argv);

// For a command line that parsed but holds a value the program refuses (the message names
// the flag): prints it the way ParseCommandLine prints its complaints; returns kUsageError.
int ReportUsageError(const CLI::App& app, const std::string& message);

}  // namespace tcfarm::cli
