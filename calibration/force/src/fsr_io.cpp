#include "calibration/force/fsr_io.h"

#include <fmt/format.h>

#include <cmath>
#include <string>

#include "common/file_io.h"

namespace hc::calib {
namespace {

// Typed field access with messages naming the key (nlohmann's get<> throws on type mismatch).
Status get_number(const Json& obj, std::string_view name, const char* key, double& out,
                  bool required) {
  const auto it = obj.find(key);
  if (it == obj.end()) {
    if (required) return invalid_argument(fmt::format("{}: {}: missing", name, key));
    return {};
  }
  if (!it->is_number())
    return invalid_argument(fmt::format("{}: {}: expected a number", name, key));
  out = it->get<double>();
  if (!std::isfinite(out)) return invalid_argument(fmt::format("{}: {}: not finite", name, key));
  return {};
}

Status get_numbers(const Json& obj, std::string_view name, const char* key,
                   std::vector<double>& out) {
  const auto it = obj.find(key);
  if (it == obj.end()) return invalid_argument(fmt::format("{}: {}: missing", name, key));
  if (!it->is_array())
    return invalid_argument(fmt::format("{}: {}: expected an array of numbers", name, key));
  out.clear();
  for (std::size_t i = 0; i < it->size(); ++i) {
    const Json& v = (*it)[i];
    if (!v.is_number() || !std::isfinite(v.get<double>()))
      return invalid_argument(fmt::format("{}: {}[{}]: expected a finite number", name, key, i));
    out.push_back(v.get<double>());
  }
  return {};
}

}  // namespace

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

Result<FsrCurve> fsr_curve_from_json(const Json& j, std::string_view name) {
  if (!j.is_object()) return invalid_argument(fmt::format("{}: expected a JSON object", name));
  const auto fmt_it = j.find("format");
  if (fmt_it == j.end() || !fmt_it->is_string() ||
      fmt_it->get<std::string>() != kFsrCalibrationFormat)
    return invalid_argument(
        fmt::format("{}: format: expected \"{}\"", name, kFsrCalibrationFormat));
  const auto ver = j.find("version");
  if (ver == j.end() || !ver->is_number_integer() ||
      ver->get<std::int64_t>() != kFsrCalibrationVersion)
    return invalid_argument(fmt::format("{}: version: expected {}", name, kFsrCalibrationVersion));
  FsrCurve c;
  if (const auto d = j.find("device"); d != j.end()) {
    if (!d->is_string())
      return invalid_argument(fmt::format("{}: device: expected a string", name));
    c.device = d->get<std::string>();
  }
  const auto model = j.find("model");
  if (model == j.end() || !model->is_string())
    return invalid_argument(
        fmt::format("{}: model: expected \"power_law\" or \"piecewise_linear\"", name));
  if (model->get<std::string>() == "power_law")
    c.model = FsrModel::kPowerLaw;
  else if (model->get<std::string>() == "piecewise_linear")
    c.model = FsrModel::kPiecewiseLinear;
  else
    return invalid_argument(
        fmt::format("{}: model: expected \"power_law\" or \"piecewise_linear\", got \"{}\"", name,
                    model->get<std::string>()));

  if (const auto pl = j.find("power_law"); pl != j.end()) {
    const std::string ctx = fmt::format("{}: power_law", name);
    if (!pl->is_object()) return invalid_argument(ctx + ": expected an object");
    FsrPowerLaw& p = c.power_law;
    HC_RETURN_IF_ERROR(get_number(*pl, ctx, "full_scale", p.full_scale, true));
    HC_RETURN_IF_ERROR(get_number(*pl, ctx, "threshold", p.threshold, true));
    HC_RETURN_IF_ERROR(get_number(*pl, ctx, "scale_n", p.scale_n, true));
    HC_RETURN_IF_ERROR(get_number(*pl, ctx, "exponent", p.exponent, true));
    HC_RETURN_IF_ERROR(get_number(*pl, ctx, "threshold_std", c.threshold_std, false));
    HC_RETURN_IF_ERROR(get_number(*pl, ctx, "scale_n_std", c.scale_n_std, false));
    HC_RETURN_IF_ERROR(get_number(*pl, ctx, "exponent_std", c.exponent_std, false));
    if (!(p.full_scale > 0.0)) return invalid_argument(ctx + ": full_scale: must be > 0");
    if (!(p.threshold >= 0.0 && p.threshold < 1.0))
      return invalid_argument(ctx + ": threshold: must be in [0, 1)");
    if (!(p.scale_n > 0.0)) return invalid_argument(ctx + ": scale_n: must be > 0");
    if (!(p.exponent > 0.0)) return invalid_argument(ctx + ": exponent: must be > 0");
    if (c.threshold_std < 0.0 || c.scale_n_std < 0.0 || c.exponent_std < 0.0)
      return invalid_argument(ctx + ": standard deviations must be >= 0");
  } else if (c.model == FsrModel::kPowerLaw) {
    return invalid_argument(fmt::format("{}: power_law: missing (model is power_law)", name));
  }

  if (const auto pw = j.find("piecewise_linear"); pw != j.end()) {
    const std::string ctx = fmt::format("{}: piecewise_linear", name);
    if (!pw->is_object()) return invalid_argument(ctx + ": expected an object");
    HC_RETURN_IF_ERROR(get_numbers(*pw, ctx, "raw", c.piecewise.raw));
    HC_RETURN_IF_ERROR(get_numbers(*pw, ctx, "force_n", c.piecewise.force_n));
    if (c.piecewise.raw.size() < 2)
      return invalid_argument(ctx + ": raw: expected at least 2 knots");
    if (c.piecewise.force_n.size() != c.piecewise.raw.size())
      return invalid_argument(fmt::format("{}: force_n: {} values for {} knots", ctx,
                                          c.piecewise.force_n.size(), c.piecewise.raw.size()));
    for (std::size_t i = 1; i < c.piecewise.raw.size(); ++i) {
      if (!(c.piecewise.raw[i] > c.piecewise.raw[i - 1]))
        return invalid_argument(fmt::format("{}: raw[{}]: knots must increase strictly", ctx, i));
      if (c.piecewise.force_n[i] < c.piecewise.force_n[i - 1])
        return invalid_argument(fmt::format("{}: force_n[{}]: forces must not decrease", ctx, i));
    }
  } else if (c.model == FsrModel::kPiecewiseLinear) {
    return invalid_argument(
        fmt::format("{}: piecewise_linear: missing (model is piecewise_linear)", name));
  }
  if (const auto fit = j.find("fit"); fit != j.end() && fit->is_object()) {
    if (const auto n = fit->find("pairs"); n != fit->end() && n->is_number_unsigned())
      c.pairs = n->get<std::size_t>();
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
