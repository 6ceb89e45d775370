#pragma once
// Internal: shared pieces of the YAML and DXF line-model loaders.

#include "evpipe/camera/line_model.hpp"

#include <string>
#include <string_view>
#include <vector>

namespace evpipe::camera::detail {

/// True when the text starts (after blank lines) with a DXF group code line "0" or "999".
bool looks_like_dxf(std::string_view text);

/// ASCII DXF → LineModel (see load_line_model()).
LineModel parse_line_model_dxf(std::string_view text, const std::string& file, std::vector<std::string>* notes);

/// File coordinates → metres. Division (not multiplication by 0.001) so that "196.5 mm" gives the correctly
/// rounded 0.1965 m; both loaders use this one function, so a YAML and a DXF of the same model agree exactly.
inline Eigen::Vector3d to_metres(double x, double y, double z, double units_per_metre) {
  return {x / units_per_metre, y / units_per_metre, z / units_per_metre};
}

}  // namespace evpipe::camera::detail
