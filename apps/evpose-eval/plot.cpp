#include "plot.hpp"

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

namespace evpose_eval {
namespace {

// Layout (pixels). Four panels stacked, sharing the time axis.
constexpr int kWidth = 1400;
constexpr int kPanelHeight = 250;
constexpr int kTitleHeight = 60;  // two lines of title
constexpr int kLeft = 110;        // room for the tick labels and the rotated axis label
constexpr int kRight = 30;
constexpr int kGap = 34;     // between panels: the tick labels of the time axis
constexpr int kBottom = 60;  // the last time axis and its label
constexpr int kShift = 4;    // sub-pixel bits of the anti-aliased polylines

const cv::Scalar kWhite(255, 255, 255);
const cv::Scalar kBlack(0, 0, 0);
const cv::Scalar kGrid(225, 225, 225);
const cv::Scalar kTruth(40, 40, 40);
const cv::Scalar kEstimate(30, 30, 220);                                           // red (BGR)
const cv::Scalar kAxisColour[3] = {{40, 40, 215}, {40, 150, 40}, {200, 110, 20}};  // x red, y green, z blue
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

struct Axes {
  cv::Rect area;
  double x0 = 0, x1 = 1, y0 = 0, y1 = 1;

  [[nodiscard]] cv::Point2d to_px(double x, double y) const {
    // Coordinates relative to `area` (drawing happens in the ROI, which clips); clamped so that a wild value
    // cannot overflow the fixed-point conversion.
    const double px = (x - x0) / (x1 - x0) * area.width;
    const double py = (1.0 - (y - y0) / (y1 - y0)) * area.height;
    return {std::clamp(px, -1e5, 1e5), std::clamp(py, -1e5, 1e5)};
  }
};

/// A "nice" tick step (1, 2 or 5 times a power of ten) giving about `target` intervals over `range`.
double nice_step(double range, int target) {
  const double raw = range / target;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double norm = raw / mag;
  const double nice = norm < 1.5 ? 1.0 : norm < 3.5 ? 2.0 : norm < 7.5 ? 5.0 : 10.0;
  return nice * mag;
}

std::string tick_label(double v, double step) {
  const int decimals = std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9)));
  if (std::abs(v) < step * 1e-6) v = 0.0;  // no "-0"
  return fmt::format("{:.{}f}", v, decimals);
}

void put_text(cv::Mat& img, const std::string& text, cv::Point org, double scale, const cv::Scalar& colour,
              int thickness = 1) {
  cv::putText(img, text, org, kFont, scale, colour, thickness, cv::LINE_AA);
}

cv::Size text_size(const std::string& text, double scale, int thickness = 1) {
  int baseline = 0;
  return cv::getTextSize(text, kFont, scale, thickness, &baseline);
}

/// Text rotated by 90 degrees (reading upwards), centred vertically on `centre_y`, left edge at `x`.
void put_vertical_text(cv::Mat& img, const std::string& text, int x, int centre_y, double scale) {
  const cv::Size s = text_size(text, scale);
  cv::Mat horizontal(s.height + 8, s.width + 4, CV_8UC3, kWhite);
  put_text(horizontal, text, cv::Point(2, s.height + 2), scale, kBlack);
  cv::Mat vertical;
  cv::rotate(horizontal, vertical, cv::ROTATE_90_COUNTERCLOCKWISE);
  const int y = std::clamp(centre_y - vertical.rows / 2, 0, img.rows - vertical.rows);
  vertical.copyTo(img(cv::Rect(x, y, vertical.cols, vertical.rows)));
}

/// Frame, grid, ticks and tick labels; the time labels under the panel when `time_labels`.
void draw_axes(cv::Mat& img, const Axes& ax, const std::string& y_label, bool time_labels) {
  const cv::Rect& a = ax.area;
  const double y_step = nice_step(ax.y1 - ax.y0, 5);
  for (double y = std::ceil(ax.y0 / y_step) * y_step; y <= ax.y1 + y_step * 1e-9; y += y_step) {
    const int py = a.y + static_cast<int>(std::lround(ax.to_px(ax.x0, y).y));
    cv::line(img, {a.x, py}, {a.x + a.width, py}, kGrid, 1);
    cv::line(img, {a.x - 6, py}, {a.x, py}, kBlack, 1);
    const std::string label = tick_label(y, y_step);
    const cv::Size s = text_size(label, 0.45);
    put_text(img, label, {a.x - 10 - s.width, py + s.height / 2}, 0.45, kBlack);
  }
  const double x_step = nice_step(ax.x1 - ax.x0, 10);
  for (double x = std::ceil(ax.x0 / x_step) * x_step; x <= ax.x1 + x_step * 1e-9; x += x_step) {
    const int px = a.x + static_cast<int>(std::lround(ax.to_px(x, ax.y0).x));
    cv::line(img, {px, a.y}, {px, a.y + a.height}, kGrid, 1);
    cv::line(img, {px, a.y + a.height}, {px, a.y + a.height + 6}, kBlack, 1);
    if (time_labels) {
      const std::string label = tick_label(x, x_step);
      const cv::Size s = text_size(label, 0.45);
      put_text(img, label, {px - s.width / 2, a.y + a.height + 10 + s.height}, 0.45, kBlack);
    }
  }
  cv::rectangle(img, a, kBlack, 1);
  put_vertical_text(img, y_label, 8, a.y + a.height / 2, 0.55);
}

/// A polyline through `pts` (plot coordinates), broken where consecutive x differ by more than `break_dx`.
void draw_series(cv::Mat& img, const Axes& ax, const std::vector<cv::Point2d>& pts, const cv::Scalar& colour,
                 int thickness, double break_dx) {
  cv::Mat roi = img(ax.area);
  std::vector<cv::Point> run;
  const auto flush = [&] {
    if (run.size() == 1) cv::circle(roi, run.front(), 2 << kShift, colour, cv::FILLED, cv::LINE_AA, kShift);
    if (run.size() > 1) cv::polylines(roi, run, false, colour, thickness, cv::LINE_AA, kShift);
    run.clear();
  };
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (i > 0 && pts[i].x - pts[i - 1].x > break_dx) flush();
    const cv::Point2d p = ax.to_px(pts[i].x, pts[i].y);
    run.emplace_back(static_cast<int>(std::lround(p.x * (1 << kShift))),
                     static_cast<int>(std::lround(p.y * (1 << kShift))));
  }
  flush();
}

void draw_legend(cv::Mat& img, const Axes& ax, const std::vector<std::pair<std::string, cv::Scalar>>& entries) {
  constexpr double kScale = 0.5;
  int width = 0;
  for (const auto& [label, colour] : entries) width = std::max(width, text_size(label, kScale).width);
  const int row = 22;
  const cv::Rect box(ax.area.x + ax.area.width - width - 60, ax.area.y + 8, width + 52,
                     row * static_cast<int>(entries.size()) + 8);
  cv::rectangle(img, box, kWhite, cv::FILLED);
  cv::rectangle(img, box, cv::Scalar(150, 150, 150), 1);
  int y = box.y + 4 + row / 2;
  for (const auto& [label, colour] : entries) {
    cv::line(img, {box.x + 8, y}, {box.x + 36, y}, colour, 2, cv::LINE_AA);
    put_text(img, label, {box.x + 44, y + 5}, kScale, kBlack);
    y += row;
  }
}

/// y range covering `always` entirely and `robust` between its 1st and 99th percentiles (so that a few wild
/// estimates do not squash the truth; they are clipped at the panel's edge), with a margin.
std::pair<double, double> y_range(std::vector<double> always, std::vector<double> robust) {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  for (const double v : always) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  if (!robust.empty()) {
    std::sort(robust.begin(), robust.end());
    const auto at = [&](double q) {
      return robust[static_cast<std::size_t>(std::lround(q * static_cast<double>(robust.size() - 1)))];
    };
    lo = std::min(lo, at(0.01));
    hi = std::max(hi, at(0.99));
  }
  if (!std::isfinite(lo)) return {-1.0, 1.0};
  const double span = std::max(hi - lo, 1.0);  // at least 1 mm tall
  const double mid = 0.5 * (lo + hi);
  return {mid - 0.55 * span, mid + 0.55 * span};
}

}  // namespace

void write_plot(const std::string& path, const PlotInput& in) {
  if (in.eval == nullptr || in.truth.empty()) throw std::invalid_argument("write_plot: nothing to draw");
  const auto& samples = in.eval->samples;
  const std::int64_t t0_us = in.truth.front().t_us;
  const auto seconds = [&](std::int64_t t_us) { return static_cast<double>(t_us - t0_us) * 1e-6; };
  double x1 = seconds(in.truth.back().t_us);
  if (x1 <= 0.0) x1 = 1e-3;

  const int height = kTitleHeight + 4 * kPanelHeight + 3 * kGap + kBottom;
  cv::Mat img(height, kWidth, CV_8UC3, kWhite);
  // The title: one line per '\n'.
  int title_y = 22;
  for (std::size_t start = 0; start <= in.title.size(); title_y += 24) {
    const auto end = std::min(in.title.find('\n', start), in.title.size());
    put_text(img, in.title.substr(start, end - start), {kLeft, title_y}, 0.55, kBlack, 1);
    start = end + 1;
  }

  const char* names[3] = {"x", "y", "z"};
  const auto panel = [&](int k) {
    return cv::Rect(kLeft, kTitleHeight + k * (kPanelHeight + kGap), kWidth - kLeft - kRight, kPanelHeight);
  };
  const double break_dx = static_cast<double>(in.max_gap_us) * 1e-6;
  for (int a = 0; a < 3; ++a) {
    std::vector<cv::Point2d> truth_pts;
    std::vector<double> truth_y;
    for (const auto& sp : in.truth) {
      truth_pts.emplace_back(seconds(sp.t_us), sp.pose.t_cam_model_m[a] * 1000.0);
      truth_y.push_back(truth_pts.back().y);
    }
    std::vector<cv::Point2d> est_pts;
    std::vector<double> est_y;
    for (const auto& s : samples) {
      est_pts.emplace_back(seconds(s.t_us), s.t_est_m[a] * 1000.0);
      est_y.push_back(est_pts.back().y);
    }
    const auto [lo, hi] = y_range(truth_y, est_y);
    const Axes ax{panel(a), 0.0, x1, lo, hi};
    draw_axes(img, ax, fmt::format("{} (mm)", names[a]), true);
    draw_series(img, ax, truth_pts, kTruth, 2, std::numeric_limits<double>::infinity());
    draw_series(img, ax, est_pts, kEstimate, 2, break_dx);
    draw_legend(img, ax,
                {{fmt::format("truth {}", names[a]), kTruth}, {fmt::format("estimate {}", names[a]), kEstimate}});
  }

  // Error per axis, estimate - truth.
  std::vector<cv::Point2d> err_pts[3];
  std::vector<double> err_y;
  for (const auto& s : samples) {
    for (int a = 0; a < 3; ++a) {
      err_pts[a].emplace_back(seconds(s.t_us), s.error_mm[a]);
      err_y.push_back(s.error_mm[a]);
    }
  }
  const auto [lo, hi] = y_range({0.0}, err_y);
  const Axes ax{panel(3), 0.0, x1, lo, hi};
  draw_axes(img, ax, "error (mm)", true);
  const int zero_y = ax.area.y + static_cast<int>(std::lround(ax.to_px(0.0, 0.0).y));
  cv::line(img, {ax.area.x, zero_y}, {ax.area.x + ax.area.width, zero_y}, cv::Scalar(120, 120, 120), 1);
  std::vector<std::pair<std::string, cv::Scalar>> legend;
  for (int a = 0; a < 3; ++a) {
    draw_series(img, ax, err_pts[a], kAxisColour[a], 2, break_dx);
    legend.emplace_back(fmt::format("error {} (est - truth)", names[a]), kAxisColour[a]);
  }
  draw_legend(img, ax, legend);
  const std::string x_label = "time since the first ground-truth pose (s)";
  const cv::Size s = text_size(x_label, 0.55);
  put_text(img, x_label, {kLeft + (kWidth - kLeft - kRight - s.width) / 2, height - 14}, 0.55, kBlack);

  bool ok = false;
  try {
    ok = cv::imwrite(path, img);
  } catch (const cv::Exception& e) {
    throw std::runtime_error(fmt::format("{}: cannot write the image: {}", path, e.what()));
  }
  if (!ok) throw std::runtime_error(fmt::format("{}: cannot write the image", path));
}

}  // namespace evpose_eval
