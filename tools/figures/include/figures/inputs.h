// What `hardcopy plot` and `hardcopy report` make of their inputs: each session (.mcap) gives its
// force curves; each samples file its probe curves, or with materials the measured-vs-simulated
// figures and the error map; two or more samples files also the materials overview (Fig. 5.7.1);
// a target samples file compares every samples input with it (Fig. 5.8.3).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "common/status.h"
#include "figures/figure.h"

namespace hc::figures {

struct FigureInputs {
  std::vector<std::string> files;      // S.mcap | SAMPLES.json
  std::vector<std::string> labels;     // legend names of the samples files (default: file stems)
  std::vector<std::string> materials;  // MATERIAL.json to simulate the samples with
  std::vector<std::string> material_labels;  // default: file stems
  std::optional<std::string> target;         // target samples file
  int simulation_steps = 8;
};

// The figure sets, in input order. kInvalidArgument naming the file for an unreadable or
// unrecognised input (a JSON document whose "format" is not hardcopy.samples, an extension other
// than .mcap / .json) and for more labels than inputs.
Result<std::vector<FigureSet>> figures_for_inputs(const FigureInputs& inputs);

// A file-system-safe name for a set's folder: letters, digits, '-', '_' and '.'.
std::string slug(std::string_view text);

}  // namespace hc::figures
