#include "calibration/force/fsr_io.h"

#include <fmt/format.h>

#include <cmath>
#include <string>

#include "common/file_io.h"
#include "common/json_reader.h"

namespace hc::calib {
Json fsr_curve_to_json(const FsrCurve& c) {
  Json j{{"format", kFsrCalibrationFormat},
         {"version", kFsrCalibrationVersion},
         {"device", c.device},
         {"model", to_string(c.model)},
         {"power_law",
          {{"full_scale", c.power_law.full_scale},
           {"threshold", c.power_law.threshold},
           {"scale_n", c.power_law.scale_n},
           {"exponent", c.power_law.exponent},
           {"threshold_std", c.threshold_std},
           {"scale_n_std", c.scale_n_std},
           {"exponent_std", c.exponent_std}}}};
  Json fit{{"pairs", c.pairs}, {"power_law", c.power_law_quality.to_json()}};
  if (c.piecewise.raw.size() >= 2) {
    j["piecewise_linear"] = {{"raw", c.piecewise.raw}, {"force_n", c.piecewise.force_n}};
    fit["piecewise_linear"] = c.piecewise_quality.to_json();
  }
  j["fit"] = fit;
  return j;
}

Result<FsrCurve> fsr_curve_from_json(const Json& json, std::string_view name) {
  const JsonNode j(json, name);
  if (!json.is_object()) return j.error("expected a JSON object");
  std::string format;
  HC_RETURN_IF_ERROR(j.get("format", format, {kFsrCalibrationFormat}));
  int version = 0;
  HC_RETURN_IF_ERROR(
      j.get("version", version, Bounds::between(kFsrCalibrationVersion, kFsrCalibrationVersion)));
  FsrCurve c;
  HC_RETURN_IF_ERROR(j.optional("device", c.device));
  std::string model;
  HC_RETURN_IF_ERROR(j.get("model", model, {"power_law", "piecewise_linear"}));
  c.model = model == "power_law" ? FsrModel::kPowerLaw : FsrModel::kPiecewiseLinear;

  if (const auto pl = j.find("power_law")) {
    HC_RETURN_IF_ERROR(pl->expect_object());
    FsrPowerLaw& p = c.power_law;
    HC_RETURN_IF_ERROR(pl->get("full_scale", p.full_scale));
    HC_RETURN_IF_ERROR(pl->get("threshold", p.threshold));
    HC_RETURN_IF_ERROR(pl->get("scale_n", p.scale_n));
    HC_RETURN_IF_ERROR(pl->get("exponent", p.exponent));
    HC_RETURN_IF_ERROR(pl->optional("threshold_std", c.threshold_std));
    HC_RETURN_IF_ERROR(pl->optional("scale_n_std", c.scale_n_std));
    HC_RETURN_IF_ERROR(pl->optional("exponent_std", c.exponent_std));
    if (!(p.full_scale > 0.0)) return pl->error("full_scale: must be > 0");
    if (!(p.threshold >= 0.0 && p.threshold < 1.0))
      return pl->error("threshold: must be in [0, 1)");
    if (!(p.scale_n > 0.0)) return pl->error("scale_n: must be > 0");
    if (!(p.exponent > 0.0)) return pl->error("exponent: must be > 0");
    if (c.threshold_std < 0.0 || c.scale_n_std < 0.0 || c.exponent_std < 0.0)
      return pl->error("standard deviations must be >= 0");
  } else if (c.model == FsrModel::kPowerLaw) {
    return j.error("power_law: missing (model is power_law)");
  }

  if (const auto pw = j.find("piecewise_linear")) {
    HC_RETURN_IF_ERROR(pw->expect_object());
    FsrPiecewiseLinear& k = c.piecewise;
    HC_RETURN_IF_ERROR(pw->get("raw", k.raw));
    HC_RETURN_IF_ERROR(pw->get("force_n", k.force_n));
    if (k.raw.size() < 2) return pw->error("raw: expected at least 2 knots");
    if (k.force_n.size() != k.raw.size())
      return pw->error(
          fmt::format("force_n: {} values for {} knots", k.force_n.size(), k.raw.size()));
    for (std::size_t i = 1; i < k.raw.size(); ++i) {
      if (!(k.raw[i] > k.raw[i - 1]))
        return pw->error(fmt::format("raw[{}]: knots must increase strictly", i));
      if (k.force_n[i] < k.force_n[i - 1])
        return pw->error(fmt::format("force_n[{}]: forces must not decrease", i));
    }
  } else if (c.model == FsrModel::kPiecewiseLinear) {
    return j.error("piecewise_linear: missing (model is piecewise_linear)");
  }
  if (const auto fit = j.find("fit"); fit && fit->json().is_object()) {
    if (const auto n = fit->find("pairs"); n && n->json().is_number_unsigned())
      c.pairs = n->json().get<std::size_t>();
  }
  return c;
}

Result<FsrCurve> parse_fsr_calibration(std::string_view text, std::string_view name) {
  HC_ASSIGN_OR_RETURN(Json j, parse_json(text, name));
  return fsr_curve_from_json(j, name);
}

Status write_fsr_calibration(const std::filesystem::path& path, const FsrCurve& curve) {
  return write_file_atomic(path, dump_json(fsr_curve_to_json(curve)));
}

Result<FsrCurve> read_fsr_calibration(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(std::string text, read_file(path, std::size_t{64} << 20));
  return parse_fsr_calibration(text, path.string());
}

}  // namespace hc::calib
