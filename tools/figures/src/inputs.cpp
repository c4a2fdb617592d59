#include "figures/inputs.h"

#include <filesystem>

#include "common/file_io.h"
#include "figures/samples_figures.h"
#include "figures/session_figures.h"
#include "processing/material/samples.h"

namespace hc::figures {
namespace {

std::string stem(const std::string& path) { return std::filesystem::path(path).stem().string(); }

Result<LabelledSamples> load(const std::string& path, std::string label) {
  Result<material::Samples> s = material::load_samples(path);
  if (!s.ok()) return s.status();
  return LabelledSamples{std::move(label), path, std::move(*s)};
}

// The "format" of a JSON input, read without loading the whole document's meaning.
Result<std::string> json_format(const std::string& path) {
  HC_ASSIGN_OR_RETURN(Json j, load_json(path));
  if (!j.is_object() || !j.contains("format") || !j["format"].is_string())
    return invalid_argument(path + ": a JSON input needs a \"format\" (expected hardcopy.samples)");
  return j["format"].get<std::string>();
}

}  // namespace

std::string slug(std::string_view text) {
  std::string s;
  for (char c : text)
    s += (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.') ? c : '_';
  return s.empty() ? "figures" : s;
}

Result<std::vector<FigureSet>> figures_for_inputs(const FigureInputs& in) {
  if (in.files.empty()) return invalid_argument("no input files");
  if (in.labels.size() > in.files.size())
    return invalid_argument("more --label values than inputs");
  if (in.material_labels.size() > in.materials.size())
    return invalid_argument("more --material-label values than --material files");
  std::vector<LabelledMaterial> materials;
  for (std::size_t i = 0; i < in.materials.size(); ++i)
    materials.push_back({i < in.material_labels.size() ? in.material_labels[i]
                                                        : stem(in.materials[i]),
                         in.materials[i]});
  std::optional<LabelledSamples> target;
  if (in.target) {
    HC_ASSIGN_OR_RETURN(LabelledSamples t, load(*in.target, stem(*in.target)));
    target = std::move(t);
  }

  std::vector<FigureSet> sets;
  std::vector<LabelledSamples> samples;
  for (std::size_t i = 0; i < in.files.size(); ++i) {
    const std::string& path = in.files[i];
    const std::string label = i < in.labels.size() ? in.labels[i] : stem(path);
    const std::string ext = std::filesystem::path(path).extension().string();
    if (ext == ".mcap") {
      Result<FigureSet> s = session_figures(path);
      if (!s.ok()) return s.status();
      sets.push_back(std::move(*s));
      continue;
    }
    if (ext != ".json")
      return invalid_argument(path + ": unknown input (expected a session .mcap or a samples .json)");
    HC_ASSIGN_OR_RETURN(std::string format, json_format(path));
    if (format != material::kSamplesFormat)
      return invalid_argument(path + ": format '" + format + "' has no figures (expected " +
                              std::string(material::kSamplesFormat) + ")");
    HC_ASSIGN_OR_RETURN(LabelledSamples ls, load(path, label));
    FitFigureOptions fit;
    fit.steps = in.simulation_steps;
    Result<FigureSet> s = materials.empty() ? samples_figures(ls) : fit_figures(ls, materials, fit);
    if (!s.ok()) return s.status().with_context(path);
    sets.push_back(std::move(*s));
    if (target) {
      Result<FigureSet> c = comparison_figures(*target, ls);
      if (!c.ok()) return c.status().with_context(path);
      sets.push_back(std::move(*c));
    }
    samples.push_back(std::move(ls));
  }
  if (samples.size() >= 2) {
    HC_ASSIGN_OR_RETURN(FigureSet m, materials_figures(samples));
    sets.push_back(std::move(m));
  }
  return sets;
}

}  // namespace hc::figures
