#include "evpipe/camera/error.hpp"

#include <utility>

namespace evpipe::camera {
namespace {
std::string compose(const std::string& file, const std::string& field, const std::string& what) {
  if (field.empty()) return file + ": " + what;
  return file + ": " + field + ": " + what;
}
}  // namespace

ModelError::ModelError(std::string file, std::string field, const std::string& what)
    : std::runtime_error(compose(file, field, what)), file_(std::move(file)), field_(std::move(field)), reason_(what) {}

}  // namespace evpipe::camera
