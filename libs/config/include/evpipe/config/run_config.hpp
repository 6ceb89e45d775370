#pragma once
// The run configuration: one typed struct per section, loaded from YAML (config/evpipe.yaml documents
// every key), overridden by the command line, validated, and printed at start.
//
// One validation layer: every key is typed, ranged and overflow-checked here, from one table (config_keys(), which
// the tests walk key by key at its bounds and with every wrong YAML node type). Unknown and duplicate keys are errors:
// a misspelt key in a production config must not silently fall back to a default. Errors throw ConfigError naming
// the file, the line and the key path (e.g. "evpipe.yaml: line 7: device.ba_filter_time_us: must be a multiple of
// 250 in [0, 1023750], got 3"); a value set on the command line is named without a line.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace evpipe::config {

class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The replay pace (--speed, source.speed) is 'max' or in [kMinSpeed, kMaxSpeed]: below 0.01 a 1 s recording takes
/// over a minute and 1e-300 would sleep for ever; above 1000 the pacing differs from 'max' by nothing measurable.
inline constexpr double kMinSpeed = 0.01;
inline constexpr double kMaxSpeed = 1000.0;
/// The shortest hop between windows: at most 1000 windows per second of stream. Each window is a pose update (and a
/// published pose), so hop_us: 1 made a 3 s replay take over a minute; 1 ms is 30 times the paper's rate.
inline constexpr std::int64_t kMinHopUs = 1000;
/// Each event is in at most this many windows (window.hop_us >= window.length_us / kMaxWindowOverlap): the denoise
/// and pose work per event grows with the overlap.
inline constexpr std::int64_t kMaxWindowOverlap = 32;

/// What one key of the run configuration accepts: config_keys() lists every key (the parser, validate() and the
/// tests use this one table).
struct KeyInfo {
  enum class Type {
    string,   ///< a string of at most max_length bytes, no NUL; non_empty if it must not be ""
    boolean,  ///< true / false
    integer,  ///< a decimal integer in [min, max], a multiple of multiple_of
    real,     ///< a finite number in [min_real, max_real]
    choice,   ///< one of `choices`
    speed,    ///< 'max' or a number in [kMinSpeed, kMaxSpeed]
    threads,  ///< 'auto' or an integer in [min, max]
    params,   ///< a map of KEY: scalar value (validated by the filter registry when the filter is built)
  };
  std::string path;  ///< "window.length_us"
  Type type = Type::string;
  std::int64_t min = 0;  ///< integer / threads: the inclusive range (window.hop_us: also at most window.length_us
  std::int64_t max = 0;  ///<   and at least length_us / kMaxWindowOverlap; batch_events: at most source_queue_events)
  std::int64_t multiple_of = 1;
  double min_real = 0.0;  ///< real: the inclusive range
  double max_real = 0.0;
  std::size_t max_length = 4096;  ///< string: PATH_MAX (LCM channels: 63, LCM_MAX_CHANNEL_NAME_LENGTH)
  bool non_empty = false;
  std::vector<std::string> choices;
  std::string reason;  ///< why this range (appended to range errors)
};
/// Every key of every section, in config/evpipe.yaml order.
const std::vector<KeyInfo>& config_keys();

struct LogConfig {
  std::string level = "info";  ///< trace | debug | info | warn | error | critical | off
};

struct SourceConfig {
  std::string replay;                         ///< recording to replay; empty = live camera
  std::optional<double> speed = 1.0;          ///< replay pace factor; nullopt = "max" (as fast as possible)
  std::int64_t batch_events = 8192;           ///< events per batch read from a file
  bool drop_out_of_order = true;              ///< drop events whose t_us goes backwards (else keep and count)
  std::int64_t discontinuity_us = 1'000'000;  ///< backward jump treated as a clock reset
  int default_width = 346;                    ///< sensor size when the file does not state it
  int default_height = 260;
  bool aedat2_flip_y = true;  ///< jAER bottom-left origin → top-left
  bool aedat2_flip_x = false;
};

struct DeviceConfig {
  std::string serial;                     ///< open this serial number; empty = first DAVIS found
  bool ba_filter = true;                  ///< FPGA background-activity filter
  std::int64_t ba_filter_time_us = 2000;  ///< its support time (250 µs steps)
  bool refractory = false;                ///< FPGA refractory-period filter
  std::int64_t refractory_time_us = 250;
  std::int64_t container_interval_us = 5000;  ///< libcaer packet container interval
  std::int64_t reconnect_interval_ms = 1000;  ///< retry period after an unplug
};

struct WindowConfig {
  std::int64_t length_us = 30'000;  ///< the paper's 30 ms windows
  std::int64_t hop_us = 30'000;     ///< hop between window starts (= length: fixed windows)
  /// Windows in which the denoiser kept no event are still cut (and a pose published for them: a still target
  /// is held, not silent) up to this long after the newest kept event; 0 = only windows holding events.
  std::int64_t max_empty_span_us = 60'000'000;
};

struct DenoiseConfig {
  /// A filter or comma-separated chain by name (`evdenoise --list-filters`); "none" = no denoising.
  std::string filter = "significance";
  /// KEY (or NAME.KEY in a chain) → value, as `evdenoise --set KEY=VALUE`; the filter validates them.
  std::vector<std::pair<std::string, std::string>> params;
  /// Threads one block of the filter is spread over (denoise::Filter::set_parallelism); 0 = auto (the cores the
  /// machine has, at most 4).
  int threads = 0;

  /// The parameters evpipe builds the filter with: `params`, plus evpipe's own defaults for the paper's curvature
  /// filter where `params` leaves them unset (docs/algorithms.md, "Singular fits" and "Adaptive threshold"):
  ///  * singular: keep — a thin edge's rank-deficient fit is kept (unless `singular` is set);
  ///  * adaptive: true, adaptive_max_threshold: 5 — the density threshold follows the measured noise rate but
  ///    never rises above the paper's 5. A `density_threshold` of the user's turns both off (a fixed threshold
  ///    stays fixed); otherwise each is added unless set (`adaptive: false` needs no cap).
  /// and for significance (docs/algorithms.md, "Significance filter"):
  ///  * exact_scores: false — the pipeline reads decisions, not scores (the same decisions, faster at high noise).
  /// Keys are looked for bare and as `curvature.KEY` (`significance.KEY`); what is added is prefixed in a chain.
  [[nodiscard]] std::vector<std::pair<std::string, std::string>> pipeline_params() const;
};

struct PoseFilesConfig {
  std::string camera;          ///< camera calibration YAML
  std::string model;           ///< line model YAML / DXF
  std::string prior;           ///< initial pose prior YAML
  std::string poses_out;       ///< trajectory CSV of published poses
  std::string ground_truth;    ///< trajectory CSV to compare the poses with (ATE in the summary); replay only
  int lost_after_windows = 3;  ///< consecutive unhealthy tracking updates before the track is declared lost
  /// Where initialisation attempts run: "on" a worker thread (the pose thread keeps publishing an
  /// `initialising` status for every window meanwhile), "off" on the pose thread (windows wait for the
  /// attempt: reproducible, what a lossless replay wants), "auto" = on, except for a replay at --speed max.
  std::string init_worker = "auto";
  /// Nice increment of that worker thread (0-19): it uses what the stages leave, but under contention from other
  /// processes a high value also slows the attempt (nice 10 gets ~10 % of a core shared with a nice-0 process).
  int init_worker_nice = 10;
  /// Fuse each track's window poses over time (a constant-velocity Kalman filter, docs/algorithms.md "Fusion over
  /// windows"); its motion model is the target's largest linear and angular acceleration.
  bool fuse_windows = true;
  /// A verified pose must stay fixed without any one of its supporting edges (no single edge carries a degree of
  /// freedom alone; docs/algorithms.md, "Pose health"): fewer wrong poses beside clutter, fewer poses.
  bool require_redundancy = false;
  /// With a prior, search the pose around the prior by the ridge contrast of the events along the projected model
  /// (docs/algorithms.md, "Direct alignment with a prior"). "auto": instead of the detected lines, for a model whose
  /// parallel lines mostly lie closer in the image than the line search resolves (a small checkerboard); "on" /
  /// "true": for every model, when the detected lines give no verified pose; "off" / "false": never.
  std::string direct_alignment = "auto";
  double max_acceleration_m_s2 = 1.0;
  double max_angular_acceleration_deg_s2 = 90.0;
};

struct LcmConfig {
  bool enabled = true;                       ///< publish poses and statistics on LCM
  std::string url;                           ///< LCM provider URL; empty = LCM's default ($LCM_DEFAULT_URL or udpm)
  std::string pose_channel = "EVPIPE_POSE";  ///< channel of the pose messages
  std::string stats_channel = "EVPIPE_STATS";
  std::int64_t stats_period_ms = 1000;  ///< statistics message period
  /// The preview for people (evpipe-view; preview_t, docs/operations.md "Watching the pipeline"): off by default.
  bool preview = false;
  double preview_hz = 10.0;  ///< previews per second when on (0.1-30)
  std::string preview_channel = "EVPIPE_PREVIEW";
};

struct PipelineConfig {
  std::int64_t source_queue_packets = 256;       ///< packets between the source and the denoise thread
  std::int64_t source_queue_events = 1'000'000;  ///< and at most this many events in them (memory bound)
  std::int64_t pose_queue_windows = 2;           ///< windows waiting for the pose thread (live: the freshest win)
  std::int64_t publish_queue = 64;               ///< poses waiting for the publish thread
};

struct RunConfig {
  LogConfig log;
  SourceConfig source;
  DeviceConfig device;
  WindowConfig window;
  DenoiseConfig denoise;
  PoseFilesConfig pose;
  LcmConfig lcm;
  PipelineConfig pipeline;

  /// Checks every key's type range (config_keys()) and the keys' consistency (hop vs length, batch vs queue);
  /// throws ConfigError naming the key. parse_config() runs it; run it again after command-line overrides.
  void validate() const;
  /// YAML text of the effective configuration (logged at start; loadable again).
  [[nodiscard]] std::string to_yaml() const;
};

/// Loads `path` over the defaults. Throws ConfigError (file, key, reason) on unreadable files, syntax errors,
/// unknown keys, and values of the wrong type or out of range.
RunConfig load_config(const std::string& path);
/// The largest run configuration load_config() reads (the shipped ones are ~10 KB): a regular file only (a FIFO,
/// device or directory is refused without blocking), checked before reading.
inline constexpr std::uint64_t kMaxConfigBytes = 1 << 20;
/// Parses YAML text (for tests); `name` is used in messages.
RunConfig parse_config(const std::string& yaml_text, const std::string& name = "<config>");

/// Parses a replay speed: "max" → nullopt, else a number in [kMinSpeed, kMaxSpeed]. Throws ConfigError.
std::optional<double> parse_speed(const std::string& text, const std::string& where);

}  // namespace evpipe::config
