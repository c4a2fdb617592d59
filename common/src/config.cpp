#include "common/config.h"

#include <fmt/format.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>
#include <cstdint>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <exception>
#include <sstream>
#include <unordered_map>

#include "common/file_io.h"

namespace hc {
namespace {

// Aliases can make a document refer to itself (&a [*a]); a recursive schema would follow such a
// cycle forever. No real config nests this deep.
constexpr std::size_t kMaxDepth = 64;
// Aliases also let a small text stand for a huge tree ("billion laughs": a list of ten aliases
// to a list of ten aliases ...). Reading stops after this many steps (values visited, key
// lookups, keys checked); a hand-written config takes a few thousand, a plan of 10 000 steps of
// 10 keys about 200 000.
constexpr std::size_t kMaxWork = std::size_t{1} << 20;
// Maps and sequences stay in memory until the read ends (for the unknown-key check); this bounds
// that memory to a few tens of MB.
constexpr std::size_t kMaxKeptNodes = std::size_t{1} << 16;
// Maps with more keys than this get a hash index, so that a reader's lookups stay O(1).
constexpr std::size_t kIndexFrom = 16;
// Enough to fix a file in one go; a file with more problems is probably not a config at all.
constexpr std::size_t kMaxReportedErrors = 50;
// Kept for sorting; beyond this only the count grows.
constexpr std::size_t kMaxStoredErrors = 1000;
constexpr std::size_t kMaxQuotedConfigChars = 60;
// A pasted paragraph as a key would make every path below it (and every message) huge.
constexpr std::size_t kMaxKeyInPath = 64;

}  // namespace

namespace detail {

struct ConfigDocument {
  std::string name;
  YAML::Node root;
};

// What the reader knows about one place in the document. Maps and sequences are owned by their
// parent (the root by the context) and live until the read ends; scalars live as long as their
// ConfigNodes. The path is built from the parent chain only when a message needs it.
struct ConfigNodeState {
  // Constructed, never assigned: YAML::Node's operator= writes through to the node it refers to.
  ConfigNodeState(const YAML::Node& n, const ConfigNodeState* p, std::string c, bool i,
                  std::size_t l, std::size_t e)
      : node(n),
        parent(p),
        component(std::move(c)),
        is_index(i),
        line(l),
        depth(p ? p->depth + 1 : 0),
        errors_before(e) {}

  std::string path() const {
    std::vector<const ConfigNodeState*> chain;
    for (const ConfigNodeState* s = this; s && s->parent; s = s->parent) chain.push_back(s);
    std::string out;
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
      const ConfigNodeState& s = **it;
      if (s.is_index) {
        out += fmt::format("[{}]", s.component);
        continue;
      }
      if (!out.empty()) out += '.';
      if (s.component.size() > kMaxKeyInPath) {
        out += fmt::format("{}...", std::string_view(s.component).substr(0, kMaxKeyInPath));
      } else {
        out += s.component;
      }
    }
    return out;
  }

  const YAML::Node node;  // a Null node for an empty value ("key:" with nothing after it)
  const ConfigNodeState* const parent;
  const std::string component;  // the key, or the index in a sequence
  const bool is_index;
  const std::size_t line;
  const std::size_t depth;
  const std::size_t errors_before;  // error_count when this node was first visited

  std::vector<std::string> known_keys;
  // Maps and sequences below, by key or index, so that two lookups of one place (has("x") then
  // required("x", ...)) share the keys asked for. One per key, or more with duplicate keys.
  std::unordered_map<std::string, std::vector<std::unique_ptr<ConfigNodeState>>> children;
  // key -> (key node, value node) for big maps; the first of duplicate keys wins, as in a scan.
  std::unordered_map<std::string, std::pair<YAML::Node, YAML::Node>> index;
  bool indexed = false;
  bool used_as_map = false;  // its keys are checked for unknown and duplicate names
  bool allow_unknown = false;
  bool shape_reported = false;  // "expected a map, got ..." said once, not once per key
  bool stopped = false;         // a depth or size limit was hit here: read nothing below
};

struct ConfigError {
  std::size_t line;
  std::string text;
};

struct ConfigContext {
  std::string name;
  std::unique_ptr<ConfigNodeState> root;
  std::vector<ConfigNodeState*> maps;  // every map visited, for the unknown-key check
  std::size_t kept_nodes = 0;
  std::vector<ConfigError> errors;  // the first kMaxStoredErrors
  std::size_t error_count = 0;      // all of them
  std::size_t work = 0;
  bool over_budget = false;

  // Records "NAME:LINE: PATH[.KEY]: what"; the path is built only for errors that are kept.
  void record(std::size_t line, const ConfigNodeState* at, std::string_view key,
              std::string_view what, bool always_keep = false) {
    ++error_count;
    if (errors.size() >= kMaxStoredErrors && !always_keep) return;
    std::string path = at ? at->path() : std::string();
    if (!key.empty()) {
      const std::string_view shown = key.substr(0, kMaxKeyInPath);
      path = path.empty() ? std::string(shown) : fmt::format("{}.{}", path, shown);
      if (key.size() > kMaxKeyInPath) path += "...";
    }
    const std::string text = path.empty() ? std::string(what) : fmt::format("{}: {}", path, what);
    errors.push_back({line, parse_error(name, line, text).message()});
  }

  // Charges `units` steps of reading (and `kept` nodes held until the end); false, reported once,
  // when the document needs too many.
  bool spend(std::size_t units, std::size_t kept = 0) {
    work += units;
    kept_nodes += kept;
    if (work <= kMaxWork && kept_nodes <= kMaxKeptNodes) return true;
    if (!over_budget)
      record(0, nullptr, "",
             fmt::format("document too large to read (over {} values, or {} maps and "
                         "sequences): do aliases repeat a large part of it?",
                         kMaxWork, kMaxKeptNodes),
             /*always_keep=*/true);
    over_budget = true;
    return false;
  }
};

}  // namespace detail

namespace {

using detail::ConfigContext;
using detail::ConfigNodeState;

std::size_t line_of(const YAML::Node& node, std::size_t fallback) {
  const YAML::Mark mark = node.Mark();
  if (mark.is_null() || mark.line < 0) return fallback;
  return static_cast<std::size_t>(mark.line) + 1;
}

// 'text' for messages: one line, control characters escaped, long values cut.
std::string quote(std::string_view text) {
  std::string out = "'";
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (i == kMaxQuotedConfigChars) {
      out += "...";
      break;
    }
    const auto c = static_cast<unsigned char>(text[i]);
    if (c == '\n') {
      out += "\\n";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c < 0x20 || c == 0x7f) {
      out += fmt::format("\\x{:02x}", c);
    } else {
      out += static_cast<char>(c);
    }
  }
  return out + "'";
}

std::string describe_node(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Scalar:
      return quote(node.Scalar());
    case YAML::NodeType::Sequence:
      return "a sequence";
    case YAML::NodeType::Map:
      return "a map";
    case YAML::NodeType::Null:
    case YAML::NodeType::Undefined:
      break;
  }
  return "an empty value";
}

// Levenshtein distance, for "did you mean".
std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t substitute = diagonal + (a[i - 1] == b[j - 1] ? 0 : 1);
      diagonal = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, substitute});
    }
  }
  return row[b.size()];
}

// " (did you mean 'exposure_s'?)" when a candidate is close enough to be a typo, else "".
template <typename Range>
std::string suggestion(std::string_view word, const Range& candidates) {
  // Typos are short; comparing a pasted paragraph against every key is wasted work.
  constexpr std::size_t kMaxWord = 64;
  if (word.size() > kMaxWord) return "";
  std::string_view best;
  std::size_t best_distance = std::numeric_limits<std::size_t>::max();
  for (const auto& candidate : candidates) {
    if (std::string_view(candidate).size() > kMaxWord) continue;
    const std::size_t d = edit_distance(word, candidate);
    if (d < best_distance) {
      best_distance = d;
      best = candidate;
    }
  }
  // A third of the word may be wrong (one slip in a short key, three in "exposure_time_s").
  if (best.empty() || best_distance > std::max<std::size_t>(1, best.size() / 3)) return "";
  return fmt::format(" (did you mean '{}'?)", best);
}

// A shared_ptr that does not own `state`: maps and sequences belong to their parent (the root to
// the context), and every ConfigNode keeps the context alive, so the tree outlives its nodes.
std::shared_ptr<ConfigNodeState> unowned(ConfigNodeState* state) {
  return std::shared_ptr<ConfigNodeState>(std::shared_ptr<ConfigNodeState>(), state);
}

// The state of `node`, found under `component` (a key or an index) of `parent`: the one made
// before for this place, or a new one. Null (error recorded) past the limits.
std::shared_ptr<ConfigNodeState> child_state(ConfigContext& context, ConfigNodeState& parent,
                                             std::string component, bool is_index,
                                             const YAML::Node& node, std::size_t line) {
  if (!node.IsMap() && !node.IsSequence())
    return std::make_shared<ConfigNodeState>(node, &parent, std::move(component), is_index, line,
                                             context.error_count);
  auto& bucket = parent.children[component];
  for (const auto& state : bucket)
    if (state->node.is(node)) return unowned(state.get());
  if (!context.spend(0, 1)) return nullptr;
  bucket.push_back(std::make_unique<ConfigNodeState>(node, &parent, std::move(component), is_index,
                                                     line, context.error_count));
  ConfigNodeState* state = bucket.back().get();
  if (node.IsMap()) context.maps.push_back(state);
  return unowned(state);
}

// Duplicate and unknown keys of one map that a reader used.
void check_keys(ConfigContext& context, const ConfigNodeState& state) {
  if (!state.node.IsMap() || !context.spend(state.node.size())) return;
  std::map<std::string, std::size_t, std::less<>> first_line;
  for (const auto& entry : state.node) {
    const YAML::Node& key = entry.first;
    const std::size_t line = line_of(key, state.line);
    if (!key.IsScalar()) {
      context.record(line, &state, "",
                     fmt::format("keys must be plain text, got {}", describe_node(key)));
      continue;
    }
    const std::string& name = key.Scalar();
    const auto [it, inserted] = first_line.emplace(name, line);
    if (!inserted) {
      context.record(line, &state, "",
                     fmt::format("duplicate key {} (first at line {})", quote(name), it->second));
      continue;
    }
    if (state.allow_unknown) continue;
    if (std::find(state.known_keys.begin(), state.known_keys.end(), name) != state.known_keys.end())
      continue;
    context.record(
        line, &state, "",
        fmt::format("unknown key {}{}", quote(name), suggestion(name, state.known_keys)));
  }
}

// Where each document of a stream starts; the parse builds nothing.
class DocumentStarts final : public YAML::EventHandler {
 public:
  void OnDocumentStart(const YAML::Mark& mark) override { starts.push_back(mark); }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t,
                const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}

  std::vector<YAML::Mark> starts;
};

// OK when `text` holds at most one document. yaml-cpp 0.7 (fixed upstream in 2024, PR #1319)
// reports an endless run of empty documents at a stray token such as a top-level ',', so
// YAML::LoadAll never returns; here the documents are counted with a bound, and a document that
// starts where the previous one did is that bug: the token is reported instead.
Status check_single_document(std::string_view text, std::string_view name) {
  std::istringstream stream{std::string(text)};
  YAML::Parser parser(stream);
  DocumentStarts documents;
  while (documents.starts.size() < 3 && parser.HandleNextDocument(documents)) {
    const auto& starts = documents.starts;
    if (starts.size() < 2) continue;
    const YAML::Mark& previous = starts[starts.size() - 2];
    const YAML::Mark& current = starts.back();
    if (current.pos == previous.pos) {
      const auto pos = static_cast<std::size_t>(std::max(current.pos, 0));
      return parse_error(std::string(name), static_cast<std::size_t>(current.line) + 1,
                         fmt::format("invalid YAML: unexpected {}",
                                     pos < text.size() ? quote(text.substr(pos, 1)) : "end"));
    }
  }
  if (documents.starts.size() > 1)
    return parse_error(std::string(name), static_cast<std::size_t>(documents.starts[1].line) + 1,
                       "expected one YAML document, but another starts here");
  return {};
}

std::optional<double> parse_double(std::string_view text) {
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  double value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty()) return std::nullopt;
  if (!std::isfinite(value)) return std::nullopt;
  return value;
}

std::optional<std::int64_t> parse_int(std::string_view text) {
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  int base = 10;
  if (text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
    base = 16;
    text.remove_prefix(2);
  }
  std::int64_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value, base);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty()) return std::nullopt;
  // from_chars would take "-5" after "0x"; a YAML hex literal has no sign inside.
  if (base == 16 && text.front() == '-') return std::nullopt;
  return value;
}

}  // namespace

// ---- Config ----

const std::string& Config::name() const { return doc_->name; }

// Offset of the first byte that is not part of well-formed UTF-8 (RFC 3629: no overlongs, no
// surrogates, at most U+10FFFF), or npos. YAML streams are Unicode text (YAML 1.2 §5.2), and every
// string read from a config may end up in JSON (session metadata), which must be UTF-8.
namespace {
std::size_t first_invalid_utf8(std::string_view s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    std::size_t len = 0;
    std::uint32_t cp = 0;
    if (c < 0x80) {
      ++i;
      continue;
    } else if ((c & 0xE0) == 0xC0) {
      len = 2, cp = c & 0x1F;
    } else if ((c & 0xF0) == 0xE0) {
      len = 3, cp = c & 0x0F;
    } else if ((c & 0xF8) == 0xF0) {
      len = 4, cp = c & 0x07;
    } else {
      return i;
    }
    if (i + len > s.size()) return i;
    for (std::size_t k = 1; k < len; ++k) {
      const auto cc = static_cast<unsigned char>(s[i + k]);
      if ((cc & 0xC0) != 0x80) return i;
      cp = (cp << 6) | (cc & 0x3F);
    }
    static constexpr std::uint32_t kMin[5] = {0, 0, 0x80, 0x800, 0x10000};
    if (cp < kMin[len] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return i;
    i += len;
  }
  return std::string_view::npos;
}
}  // namespace

// The text is checked for UTF-8 before parsing, but yaml-cpp decodes the escapes \N and \_ (and a
// raw NUL byte followed by _, as fuzz_plan found) to the single bytes 0x85 and 0xA0, not to their
// UTF-8 encodings: its strings (keys too) are checked again where they are read.
constexpr std::string_view kNotUtf8Hint =
    "(yaml-cpp decodes the escapes \\N and \\_ to single bytes: write the character itself)";

Result<Config> parse_config(std::string_view text, std::string_view name) {
  if (const std::size_t bad = first_invalid_utf8(text); bad != std::string_view::npos) {
    const auto line =
        static_cast<std::size_t>(std::count(text.begin(), text.begin() + bad, '\n')) + 1;
    return parse_error(std::string(name), line,
                       fmt::format("not UTF-8 text (byte offset {})", bad));
  }
  YAML::Node root;
  try {
    HC_RETURN_IF_ERROR(check_single_document(text, name));
    root = YAML::Load(std::string(text));
  } catch (const YAML::ParserException& e) {
    const std::size_t line = e.mark.is_null() ? 0 : static_cast<std::size_t>(e.mark.line) + 1;
    return parse_error(std::string(name), line, fmt::format("invalid YAML: {}", e.msg));
  } catch (const YAML::Exception& e) {
    return parse_error(std::string(name), 0, fmt::format("invalid YAML: {}", e.msg));
  } catch (const std::exception& e) {
    return parse_error(std::string(name), 0, fmt::format("cannot parse YAML: {}", e.what()));
  }
  return Config(std::make_shared<const detail::ConfigDocument>(
      detail::ConfigDocument{std::string(name), root}));
}

Result<Config> load_config(const std::filesystem::path& path) {
  HC_ASSIGN_OR_RETURN(std::string text, read_file(path, kMaxConfigBytes));
  return parse_config(text, path.string());
}

// ---- Bounds ----

// ---- ConfigNode: maps and sequences ----

bool ConfigNode::has(std::string_view key) { return find(key).has_value(); }

std::optional<ConfigNode> ConfigNode::find(std::string_view key) {
  ConfigNodeState& s = *state_;
  s.used_as_map = true;
  if (std::find(s.known_keys.begin(), s.known_keys.end(), key) == s.known_keys.end())
    s.known_keys.emplace_back(key);
  const YAML::Node& node = s.node;
  if (node.IsNull()) return std::nullopt;
  if (!node.IsMap()) {
    if (!s.shape_reported) error(fmt::format("expected a map, got {}", describe_node(node)));
    s.shape_reported = true;
    return std::nullopt;
  }
  if (!can_descend(1)) return std::nullopt;
  // (key node, value node). Copies, never assignments: YAML::Node's operator= writes through.
  std::optional<std::pair<YAML::Node, YAML::Node>> found;
  if (node.size() > kIndexFrom) {
    if (!s.indexed) {
      if (!context_->spend(node.size())) return std::nullopt;
      for (const auto& entry : node)
        if (entry.first.IsScalar())
          s.index.try_emplace(entry.first.Scalar(), entry.first, entry.second);
      s.indexed = true;
    }
    const auto it = s.index.find(std::string(key));
    if (it != s.index.end()) found.emplace(it->second);
  } else {
    for (const auto& entry : node) {
      if (entry.first.IsScalar() && entry.first.Scalar() == key) {
        found.emplace(entry.first, entry.second);
        break;
      }
    }
  }
  if (!found) return std::nullopt;
  const auto& [key_node, value_node] = *found;
  // An empty value has no useful mark of its own (yaml-cpp puts it on the next line).
  const std::size_t key_line = line_of(key_node, s.line);
  const std::size_t line = value_node.IsNull() ? key_line : line_of(value_node, key_line);
  auto child = child_state(*context_, s, std::string(key), false, value_node, line);
  if (!child) return std::nullopt;
  return ConfigNode(context_, std::move(child));
}

std::optional<std::vector<std::pair<std::string, ConfigNode>>> ConfigNode::entries() {
  ConfigNodeState& s = *state_;
  s.used_as_map = true;
  s.allow_unknown = true;
  const YAML::Node& node = s.node;
  std::vector<std::pair<std::string, ConfigNode>> out;
  if (node.IsNull()) return out;
  if (!node.IsMap()) {
    if (!s.shape_reported) error(fmt::format("expected a map, got {}", describe_node(node)));
    s.shape_reported = true;
    return std::nullopt;
  }
  if (!can_descend(node.size())) return std::nullopt;
  for (const auto& entry : node) {
    if (!entry.first.IsScalar()) continue;  // check_keys reports it
    const std::string& key = entry.first.Scalar();
    if (first_invalid_utf8(key) != std::string_view::npos) {
      error(fmt::format("a key that is not UTF-8 {}", kNotUtf8Hint));
      return std::nullopt;
    }
    const std::size_t key_line = line_of(entry.first, s.line);
    const std::size_t line = entry.second.IsNull() ? key_line : line_of(entry.second, key_line);
    auto child = child_state(*context_, s, key, false, entry.second, line);
    if (!child) return std::nullopt;
    out.emplace_back(key, ConfigNode(context_, std::move(child)));
  }
  return out;
}

std::optional<std::vector<ConfigNode>> ConfigNode::elements() {
  ConfigNodeState& s = *state_;
  const YAML::Node& node = s.node;
  std::vector<ConfigNode> out;
  if (node.IsNull()) return out;
  if (!node.IsSequence()) {
    if (!s.shape_reported) error(fmt::format("expected a sequence, got {}", describe_node(node)));
    s.shape_reported = true;
    return std::nullopt;
  }
  if (!can_descend(node.size())) return std::nullopt;
  std::size_t i = 0;
  for (const auto& element : node) {
    const std::size_t line = element.IsNull() ? s.line : line_of(element, s.line);
    auto child = child_state(*context_, s, std::to_string(i), true, element, line);
    if (!child) return std::nullopt;
    out.push_back(ConfigNode(context_, std::move(child)));
    ++i;
  }
  return out;
}

// ---- ConfigNode: values ----

bool ConfigNode::get(double& out, const Bounds& bounds) {
  const YAML::Node& n = state_->node;
  const std::string expected = bounds.describe("a number");
  if (!n.IsScalar()) {
    error(fmt::format("expected {}, got {}", expected, describe_node(n)));
    return false;
  }
  const std::optional<double> value = parse_double(n.Scalar());
  if (!value) {
    error(fmt::format("expected {}, got {}", expected, quote(n.Scalar())));
    return false;
  }
  if (!bounds.contains(*value)) {
    error(fmt::format("expected {}, got {}", expected, n.Scalar()));
    return false;
  }
  out = *value;
  return true;
}

bool ConfigNode::get(std::int64_t& out, const Bounds& bounds) {
  const YAML::Node& n = state_->node;
  const std::string expected = bounds.describe("an integer");
  if (!n.IsScalar()) {
    error(fmt::format("expected {}, got {}", expected, describe_node(n)));
    return false;
  }
  const std::optional<std::int64_t> value = parse_int(n.Scalar());
  if (!value) {
    error(fmt::format("expected {}, got {}", expected, quote(n.Scalar())));
    return false;
  }
  if (!bounds.contains(static_cast<double>(*value))) {
    error(fmt::format("expected {}, got {}", expected, n.Scalar()));
    return false;
  }
  out = *value;
  return true;
}

bool ConfigNode::get(bool& out) {
  const YAML::Node& n = state_->node;
  bool value = false;
  if (!n.IsScalar() || !YAML::convert<bool>::decode(n, value)) {
    error(fmt::format("expected true or false, got {}", describe_node(n)));
    return false;
  }
  out = value;
  return true;
}

bool ConfigNode::get(std::string& out) {
  const YAML::Node& n = state_->node;
  if (!n.IsScalar()) {
    error(fmt::format("expected a string, got {}", describe_node(n)));
    return false;
  }
  if (const std::size_t bad = first_invalid_utf8(n.Scalar()); bad != std::string_view::npos) {
    error(fmt::format("a string that is not UTF-8 at byte {} {}", bad, kNotUtf8Hint));
    return false;
  }
  out = n.Scalar();
  return true;
}

bool ConfigNode::get(std::string& out, std::initializer_list<std::string_view> choices) {
  const std::vector<std::string_view> names(choices);
  const std::optional<std::size_t> index = choose(names);
  if (!index) return false;
  out = std::string(names[*index]);
  return true;
}

std::optional<std::size_t> ConfigNode::choose(std::span<const std::string_view> names) {
  const YAML::Node& n = state_->node;
  std::string expected = "one of ";
  for (std::size_t i = 0; i < names.size(); ++i)
    expected += fmt::format("{}{}", i ? ", " : "", names[i]);
  if (!n.IsScalar()) {
    error(fmt::format("expected {}, got {}", expected, describe_node(n)));
    return std::nullopt;
  }
  const std::string& text = n.Scalar();
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == text) return i;
  error(fmt::format("expected {}, got {}{}", expected, quote(text), suggestion(text, names)));
  return std::nullopt;
}

bool ConfigNode::required(std::string_view key, std::string& out,
                          std::initializer_list<std::string_view> choices) {
  std::optional<ConfigNode> value = find(key);
  if (!value) {
    missing(key);
    return false;
  }
  return value->get(out, choices);
}

bool ConfigNode::optional(std::string_view key, std::string& out,
                          std::initializer_list<std::string_view> choices) {
  std::optional<ConfigNode> value = find(key);
  return value && value->get(out, choices);
}

// ---- ConfigNode: errors ----

void ConfigNode::error(std::string_view message) {
  context_->record(state_->line, state_.get(), "", message);
}

void ConfigNode::error(std::string_view key, std::string_view message) {
  std::size_t line = state_->line;
  const YAML::Node& node = state_->node;
  if (node.IsMap()) {
    for (const auto& entry : node) {
      if (entry.first.IsScalar() && entry.first.Scalar() == key) {
        line = line_of(entry.first, line);
        break;
      }
    }
  }
  context_->record(line, state_.get(), key, message);
}

void ConfigNode::allow_unknown_keys() { state_->allow_unknown = true; }

std::string ConfigNode::path() const { return state_->path(); }

std::size_t ConfigNode::line() const { return state_->line; }

Status ConfigNode::status() const {
  const std::size_t before = state_->errors_before;
  const std::size_t n = context_->error_count - before;
  if (n == 0) return {};
  if (before >= context_->errors.size())
    return invalid_argument(fmt::format("{}: {} problems", context_->name, n));
  const std::string& first = context_->errors[before].text;
  if (n == 1) return invalid_argument(first);
  return invalid_argument(fmt::format("{} (and {} more)", first, n - 1));
}

void ConfigNode::missing(std::string_view key) {
  // When the node is not a map at all, that one message says it; a "missing" per key is noise.
  if (state_->shape_reported || state_->stopped || context_->over_budget) return;
  context_->record(state_->line, state_.get(), key, "required key is missing");
}

void ConfigNode::wrong_size(std::size_t expected, std::size_t got) {
  error(fmt::format("expected a sequence of {} elements, got {}", expected, got));
}

bool ConfigNode::can_descend(std::size_t children) {
  if (state_->stopped) return false;
  if (state_->depth + 1 > kMaxDepth) {
    error(fmt::format("nested deeper than {} levels", kMaxDepth));
    state_->stopped = true;
    return false;
  }
  if (!context_->spend(children)) {
    state_->stopped = true;
    return false;
  }
  return true;
}

std::size_t ConfigNode::begin_struct() {
  // A struct's keys are all it accepts: any other key in its map is unknown.
  state_->used_as_map = true;
  return context_->error_count;
}

bool ConfigNode::end_struct(std::size_t errors_before, const Status& status) {
  // A Status the getters did not record (a read()'s own check, a validate()) is recorded here, at
  // the struct's line; one they did record is not repeated.
  if (!status.ok() && context_->error_count == errors_before) error(status.message());
  return context_->error_count == errors_before;
}

// ---- Reading a document ----

Status read_config(const Config& config, const std::function<Status(ConfigNode)>& read) {
  const detail::ConfigDocument& doc = *config.doc_;
  auto context = std::make_shared<ConfigContext>();
  context->name = doc.name;
  try {
    // An empty document's mark points past its end; line 1 stands for the whole file.
    const std::size_t root_line = doc.root.IsNull() ? 1 : line_of(doc.root, 1);
    context->root = std::make_unique<ConfigNodeState>(doc.root, nullptr, "", false, root_line, 0);
    if (doc.root.IsMap()) context->maps.push_back(context->root.get());
    ConfigNode root(context, unowned(context->root.get()));
    root.end_struct(0, read(root));
    for (const ConfigNodeState* state : context->maps)
      if (state->used_as_map) check_keys(*context, *state);
  } catch (const YAML::Exception& e) {
    // Getters check node types first, so this is a bug here, not a bad file.
    return internal_error(fmt::format("{}: reading config: {}", doc.name, e.what()));
  }
  std::vector<detail::ConfigError>& errors = context->errors;
  if (context->error_count == 0) return {};
  std::stable_sort(errors.begin(), errors.end(),
                   [](const auto& a, const auto& b) { return a.line < b.line; });
  std::string message;
  for (std::size_t i = 0; i < errors.size() && i < kMaxReportedErrors; ++i)
    message += fmt::format("{}{}", i ? "\n" : "", errors[i].text);
  const std::size_t reported = std::min(errors.size(), kMaxReportedErrors);
  if (context->error_count > reported)
    message += fmt::format("\n{}: and {} more problems", doc.name, context->error_count - reported);
  return invalid_argument(std::move(message));
}

}  // namespace hc
