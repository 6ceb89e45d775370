#pragma once
// The one error type of evpipe::camera's loaders (camera calibration, line model, pose prior, trajectory CSV).

#include <stdexcept>
#include <string>

namespace evpipe::camera {

/// A calibration, model, prior or trajectory file that cannot be used. The message is
/// "<file>: <field>: <what>" (or "<file>: <what>" when no single field is at fault), e.g.
/// "cam.yaml: camera.fx: must be > 0, got -3", "model.yaml: model.lines[3]: zero-length segment",
/// "model.dxf: line 57: LINE entity #2 has no end point y (group 21)", "traj.csv: line 4: column qw: ...".
class ModelError : public std::runtime_error {
 public:
  ModelError(std::string file, std::string field, const std::string& what);

  [[nodiscard]] const std::string& file() const noexcept { return file_; }
  /// YAML key path ("camera.fx", "model.lines[3]") or "line N" for DXF/CSV; empty for whole-file problems.
  [[nodiscard]] const std::string& field() const noexcept { return field_; }
  [[nodiscard]] const std::string& reason() const noexcept { return reason_; }

 private:
  std::string file_;
  std::string field_;
  std::string reason_;
};

}  // namespace evpipe::camera
