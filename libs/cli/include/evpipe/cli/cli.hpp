#pragma once
// The programs' command lines: a thin, compiled front over CLI11. CLI11 (Debian's 2.1.2) is header-only and its
// parser, help formatter and validators were compiled again in every program (~8 s each, per build preset); here
// they are compiled once, in cli.cpp, and the programs include only this header. The names follow CLI11's, so a
// program reads as a CLI11 program: options bind to variables, a check or a relation is chained on the option.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace CLI {
class App;
class Option;
class Validator;
}  // namespace CLI

namespace evpipe::cli {

/// A check of an option's value (CLI11's validators); its text is shown in --help.
class Validator {
 public:
  explicit Validator(const CLI::Validator& v);
  Validator(const Validator&);
  Validator& operator=(const Validator&);
  ~Validator();
  [[nodiscard]] const CLI::Validator& get() const noexcept { return *impl_; }

 private:
  std::unique_ptr<CLI::Validator> impl_;
};

/// CLI::ExistingFile, PositiveNumber, NonNegativeNumber.
Validator existing_file();
Validator positive_number();
Validator non_negative_number();
/// CLI::Range in the bounds' type (give them the option's type): --help shows them as written, and the check reads
/// the value as that type (range(1, 8) on a double option refuses 2.5).
Validator range(int min, int max);
Validator range(std::int64_t min, std::int64_t max);
Validator range(std::size_t min, std::size_t max);
Validator range(double min, double max);
/// CLI::IsMember: one of these words.
Validator is_member(std::vector<std::string> words);

enum class MultiOptionPolicy { throw_error, take_last, take_first, join, take_all };

/// One option or flag of an App (owned by it); the setters return the option, for chaining.
class Option {
 public:
  explicit Option(CLI::Option* option) noexcept : option_(option) {}
  Option* check(const Validator& validator);
  Option* required();
  Option* excludes(Option* other);
  Option* capture_default_str();
  Option* default_str(const std::string& text);
  Option* delimiter(char separator);
  Option* expected(int values);
  Option* allow_extra_args(bool allow);
  Option* multi_option_policy(MultiOptionPolicy policy);
  /// How many times it was given on the command line.
  [[nodiscard]] std::size_t count() const;
  [[nodiscard]] std::string get_name() const;
  /// The type shown in --help: "FLOAT", "INT", "TEXT", ..., followed by ":" and the checks when it has any.
  [[nodiscard]] std::string get_type_name() const;
  /// The texts given for it, as typed.
  [[nodiscard]] std::vector<std::string> results() const;

 private:
  CLI::Option* option_;
};

class App {
 public:
  explicit App(const std::string& description);
  App(const App&) = delete;
  App& operator=(const App&) = delete;
  ~App();

  /// An option (a name "--x", "-x,--x", or a positional "NAME") read into `target`. Defined for the types the
  /// programs read: std::string, std::vector<std::string>, double, the integer types, std::optional<std::string> and
  /// std::optional<double> (empty unless given).
  template <class T>
  Option* add_option(const std::string& name, T& target, const std::string& description = {});
  /// A flag: "--x" sets `target`, "!--no-x" clears it.
  Option* add_flag(const std::string& name, bool& target, const std::string& description = {});
  void footer(const std::string& text);
  void set_version_flag(const std::string& name, const std::string& version);
  /// --help shows the default (the variable's value before parsing) of every option added after this.
  void always_capture_default();
  /// The options added through add_option / add_flag, in order.
  [[nodiscard]] const std::vector<std::unique_ptr<Option>>& options() const noexcept { return options_; }

  /// Parses the command line. Empty: go on. Otherwise the program's exit status, with CLI11's text printed: 0
  /// after --help or --version, 2 for a usage error (the programs' convention; CLI11's own codes are not kept).
  [[nodiscard]] std::optional<int> parse(int argc, const char* const* argv);

 private:
  Option* keep(CLI::Option* option);

  std::unique_ptr<CLI::App> app_;
  std::vector<std::unique_ptr<Option>> options_;
};

}  // namespace evpipe::cli
