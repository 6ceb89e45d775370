#include "evpipe/cli/cli.hpp"

#include <CLI/CLI.hpp>

#include <array>
#include <optional>
#include <utility>

namespace evpipe::cli {

Validator::Validator(const CLI::Validator& v) : impl_(std::make_unique<CLI::Validator>(v)) {}
Validator::Validator(const Validator& other) : impl_(std::make_unique<CLI::Validator>(*other.impl_)) {}
Validator& Validator::operator=(const Validator& other) {
  if (this != &other) impl_ = std::make_unique<CLI::Validator>(*other.impl_);
  return *this;
}
Validator::~Validator() = default;

Validator existing_file() {
  return Validator(CLI::ExistingFile);
}
Validator positive_number() {
  return Validator(CLI::PositiveNumber);
}
Validator non_negative_number() {
  return Validator(CLI::NonNegativeNumber);
}
Validator range(int min, int max) {
  return Validator(CLI::Range(min, max));
}
Validator range(std::int64_t min, std::int64_t max) {
  return Validator(CLI::Range(min, max));
}
Validator range(std::size_t min, std::size_t max) {
  return Validator(CLI::Range(min, max));
}
Validator range(double min, double max) {
  return Validator(CLI::Range(min, max));
}
Validator is_member(std::vector<std::string> words) {
  return Validator(CLI::IsMember(std::move(words)));
}

Option* Option::check(const Validator& validator) {
  option_->check(validator.get());
  return this;
}
Option* Option::required() {
  option_->required();
  return this;
}
Option* Option::excludes(Option* other) {
  option_->excludes(other->option_);
  return this;
}
Option* Option::capture_default_str() {
  option_->capture_default_str();
  return this;
}
Option* Option::default_str(const std::string& text) {
  option_->default_str(text);
  return this;
}
Option* Option::delimiter(char separator) {
  option_->delimiter(separator);
  return this;
}
Option* Option::expected(int values) {
  option_->expected(values);
  return this;
}
Option* Option::allow_extra_args(bool allow) {
  option_->allow_extra_args(allow);
  return this;
}
Option* Option::multi_option_policy(MultiOptionPolicy policy) {
  // In the order of MultiOptionPolicy's values.
  static constexpr std::array kPolicies{CLI::MultiOptionPolicy::Throw, CLI::MultiOptionPolicy::TakeLast,
                                        CLI::MultiOptionPolicy::TakeFirst, CLI::MultiOptionPolicy::Join,
                                        CLI::MultiOptionPolicy::TakeAll};
  option_->multi_option_policy(kPolicies.at(static_cast<std::size_t>(policy)));
  return this;
}
std::size_t Option::count() const {
  return option_->count();
}
std::string Option::get_name() const {
  return option_->get_name();
}
std::string Option::get_type_name() const {
  return option_->get_type_name();
}
std::vector<std::string> Option::results() const {
  return option_->results();
}

App::App(const std::string& description) : app_(std::make_unique<CLI::App>(description)) {}
App::~App() = default;

Option* App::keep(CLI::Option* option) {
  options_.push_back(std::make_unique<Option>(option));
  return options_.back().get();
}

template <class T>
Option* App::add_option(const std::string& name, T& target, const std::string& description) {
  return keep(app_->add_option(name, target, description));
}
// The types the programs read (a program reading another type fails to link: add it here).
template Option* App::add_option(const std::string&, std::string&, const std::string&);
template Option* App::add_option(const std::string&, std::vector<std::string>&, const std::string&);
template Option* App::add_option(const std::string&, double&, const std::string&);
template Option* App::add_option(const std::string&, int&, const std::string&);
template Option* App::add_option(const std::string&, unsigned&, const std::string&);
template Option* App::add_option(const std::string&, long&, const std::string&);
template Option* App::add_option(const std::string&, unsigned long&, const std::string&);
template Option* App::add_option(const std::string&, long long&, const std::string&);
template Option* App::add_option(const std::string&, unsigned long long&, const std::string&);
template Option* App::add_option(const std::string&, std::optional<std::string>&, const std::string&);
template Option* App::add_option(const std::string&, std::optional<double>&, const std::string&);

Option* App::add_flag(const std::string& name, bool& target, const std::string& description) {
  return keep(app_->add_flag(name, target, description));
}
void App::footer(const std::string& text) {
  app_->footer(text);
}
void App::set_version_flag(const std::string& name, const std::string& version) {
  app_->set_version_flag(name, version);
}
void App::always_capture_default() {
  app_->option_defaults()->always_capture_default();
}

std::optional<int> App::parse(int argc, const char* const* argv) {
  try {
    app_->parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app_->exit(e);
    return code == 0 ? 0 : 2;
  }
  return std::nullopt;
}

}  // namespace evpipe::cli
