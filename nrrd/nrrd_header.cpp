#include "nrrd/nrrd_header.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>
#include <map>

namespace typemerge::nrrd {
namespace {

using volume_file::SampleType;

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::vector<std::string_view> words(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t at = 0;
  while (at < s.size()) {
    while (at < s.size() && std::isspace(static_cast<unsigned char>(s[at]))) ++at;
    std::size_t end = at;
    while (end < s.size() && !std::isspace(static_cast<unsigned char>(s[end]))) ++end;
    if (end > at) out.push_back(s.substr(at, end - at));
    at = end;
  }
  return out;
}

std::optional<std::int64_t> parse_int(std::string_view s) {
  s = trim(s);
  std::int64_t v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size()) return std::nullopt;
  return v;
}

std::optional<double> parse_double(std::string_view s) {
  s = trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  double v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::optional<SampleType> sample_type(std::string_view text) {
  static const std::map<std::string, SampleType, std::less<>> types = {
      {"signed char", SampleType::int8},
      {"int8", SampleType::int8},
      {"int8_t", SampleType::int8},
      {"uchar", SampleType::uint8},
      {"unsigned char", SampleType::uint8},
      {"uint8", SampleType::uint8},
      {"uint8_t", SampleType::uint8},
      {"short", SampleType::int16},
      {"short int", SampleType::int16},
      {"signed short", SampleType::int16},
      {"signed short int", SampleType::int16},
      {"int16", SampleType::int16},
      {"int16_t", SampleType::int16},
      {"ushort", SampleType::uint16},
      {"unsigned short", SampleType::uint16},
      {"unsigned short int", SampleType::uint16},
      {"uint16", SampleType::uint16},
      {"uint16_t", SampleType::uint16},
      {"int", SampleType::int32},
      {"signed int", SampleType::int32},
      {"int32", SampleType::int32},
      {"int32_t", SampleType::int32},
      {"uint", SampleType::uint32},
      {"unsigned int", SampleType::uint32},
      {"uint32", SampleType::uint32},
      {"uint32_t", SampleType::uint32},
      {"longlong", SampleType::int64},
      {"long long", SampleType::int64},
      {"long long int", SampleType::int64},
      {"signed long long", SampleType::int64},
      {"signed long long int", SampleType::int64},
      {"int64", SampleType::int64},
      {"int64_t", SampleType::int64},
      {"ulonglong", SampleType::uint64},
      {"unsigned long long", SampleType::uint64},
      {"unsigned long long int", SampleType::uint64},
      {"uint64", SampleType::uint64},
      {"uint64_t", SampleType::uint64},
      {"float", SampleType::float32},
      {"double", SampleType::float64}};
  const auto it = types.find(lower(trim(text)));
  if (it == types.end()) return std::nullopt;
  return it->second;
}

// "(a,b,c)" → the vector; "none" → nullopt. Throws on anything else.
std::optional<core::Vec3> parse_vector(std::string_view text, const char* field) {
  text = trim(text);
  if (text == "none") return std::nullopt;
  if (text.size() < 2 || text.front() != '(' || text.back() != ')') {
    throw ReadError(std::string("NRRD ") + field + ": a vector is not (x,y,z)");
  }
  text = text.substr(1, text.size() - 2);
  core::Vec3 v{};
  for (int c = 0; c < 3; ++c) {
    const std::size_t comma = c < 2 ? text.find(',') : text.size();
    if (comma == std::string_view::npos) {
      throw ReadError(std::string("NRRD ") + field + ": a vector needs three components");
    }
    const auto value = parse_double(text.substr(0, comma));
    if (!value)
      throw ReadError(std::string("NRRD ") + field + ": a component is not a finite number");
    v[c] = *value;
    text = c < 2 ? text.substr(comma + 1) : std::string_view{};
  }
  return v;
}

// Vectors separated by spaces, each in parentheses (no spaces inside are assumed... but
// tolerated: a vector runs to its closing parenthesis).
std::vector<std::optional<core::Vec3>> parse_vectors(std::string_view text, const char* field) {
  std::vector<std::optional<core::Vec3>> out;
  std::size_t at = 0;
  while (at < text.size()) {
    while (at < text.size() && std::isspace(static_cast<unsigned char>(text[at]))) ++at;
    if (at >= text.size()) break;
    std::size_t end = at;
    if (text[at] == '(') {
      end = text.find(')', at);
      if (end == std::string_view::npos)
        throw ReadError(std::string("NRRD ") + field + ": unclosed (");
      ++end;
    } else {
      while (end < text.size() && !std::isspace(static_cast<unsigned char>(text[end]))) ++end;
    }
    out.push_back(parse_vector(text.substr(at, end - at), field));
    at = end;
  }
  return out;
}

// x and y signs that take the named space to LPS; nullopt for an unknown space.
std::optional<std::array<double, 3>> space_to_lps(const std::string& space) {
  if (space == "left-posterior-superior" || space == "lps") return std::array<double, 3>{1, 1, 1};
  if (space == "right-anterior-superior" || space == "ras") return std::array<double, 3>{-1, -1, 1};
  if (space == "left-anterior-superior" || space == "las") return std::array<double, 3>{1, -1, 1};
  return std::nullopt;
}

struct SegmentKeys {
  std::optional<std::string> name;
  std::optional<std::array<std::uint8_t, 3>> srgb;
  std::optional<std::int64_t> label;
  std::optional<std::int64_t> layer;
};

// "Segment12_Name" → (12, "Name").
bool segment_key(std::string_view key, std::int64_t& index, std::string_view& field) {
  if (key.substr(0, 7) != "Segment") return false;
  const std::size_t underscore = key.find('_');
  if (underscore == std::string_view::npos || underscore == 7) return false;
  const auto n = parse_int(key.substr(7, underscore - 7));
  if (!n || *n < 0 || *n > 1'000'000) return false;
  index = *n;
  field = key.substr(underscore + 1);
  return true;
}

std::optional<std::array<std::uint8_t, 3>> parse_colour(std::string_view text) {
  const auto parts = words(text);
  if (parts.size() != 3) return std::nullopt;
  std::array<std::uint8_t, 3> srgb{};
  for (int c = 0; c < 3; ++c) {
    const auto v = parse_double(parts[static_cast<std::size_t>(c)]);
    if (!v) return std::nullopt;
    srgb[static_cast<std::size_t>(c)] =
        static_cast<std::uint8_t>(std::lround(std::clamp(*v, 0.0, 1.0) * 255.0));
  }
  return srgb;
}

}  // namespace

std::uint64_t NrrdHeader::samples() const {
  return static_cast<std::uint64_t>(size.voxels()) * layers;
}

std::uint64_t NrrdHeader::data_bytes() const { return samples() * volume_file::sample_bytes(type); }

NrrdHeader parse_nrrd_header(std::string_view text) {
  if (text.substr(0, 7) != "NRRD000" || text.size() < 8 ||
      !std::isdigit(static_cast<unsigned char>(text[7]))) {
    throw ReadError("not a NRRD file (no NRRD000X magic)");
  }
  NrrdHeader header;
  std::map<std::string, std::string> fields;
  std::map<std::int64_t, SegmentKeys> segment_keys;
  std::size_t at = text.find('\n');
  bool ended = false;
  if (at == std::string_view::npos) throw ReadError("the NRRD header is truncated");
  ++at;
  while (at < text.size()) {
    std::size_t end = text.find('\n', at);
    const bool last = end == std::string_view::npos;
    if (last) end = text.size();
    std::string_view line = text.substr(at, end - at);
    at = last ? text.size() : end + 1;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.empty()) {
      ended = true;
      break;
    }
    if (line.front() == '#') continue;  // comment: never kept
    if (const std::size_t kv = line.find(":="); kv != std::string_view::npos) {
      std::int64_t index = 0;
      std::string_view field;
      if (!segment_key(line.substr(0, kv), index, field)) continue;  // other key/values dropped
      header.segmentation = true;
      const std::string_view value = trim(line.substr(kv + 2));
      SegmentKeys& keys = segment_keys[index];
      if (field == "Name") keys.name = std::string(value.substr(0, 256));
      if (field == "Color") keys.srgb = parse_colour(value);
      if (field == "LabelValue") keys.label = parse_int(value);
      if (field == "Layer") keys.layer = parse_int(value);
      continue;
    }
    const std::size_t colon = line.find(':');
    if (colon == std::string_view::npos) {
      throw ReadError("the NRRD header has a line that is neither a field nor a key/value");
    }
    fields[lower(trim(line.substr(0, colon)))] = std::string(trim(line.substr(colon + 1)));
  }
  header.header_bytes = at;
  auto field = [&](std::initializer_list<const char*> names) -> const std::string* {
    for (const char* name : names) {
      if (auto it = fields.find(name); it != fields.end()) return &it->second;
    }
    return nullptr;
  };

  // Detached data (.nhdr) has no blank line: the header is the whole text.
  if (const std::string* data_file = field({"data file", "datafile"})) {
    const auto parts = words(*data_file);
    if (parts.size() != 1 || parts[0] == "LIST") {
      throw ReadError("NRRD data file lists or patterns (several data files) are not supported");
    }
    header.data_file = std::string(parts[0]);
  } else if (!ended) {
    throw ReadError("the NRRD header is truncated (no empty line before the data)");
  }

  const std::string* type = field({"type"});
  if (type == nullptr) throw ReadError("NRRD header without a type");
  const auto sample = sample_type(*type);
  if (!sample) throw ReadError("NRRD type is not a supported integer or float type");
  header.type = *sample;

  const std::string* dimension_text = field({"dimension"});
  const auto dimension = dimension_text ? parse_int(*dimension_text) : std::nullopt;
  if (!dimension || (*dimension != 3 && *dimension != 4)) {
    throw ReadError("NRRD dimension must be 3 (a volume) or 4 (layers of a volume)");
  }
  const std::size_t ndim = static_cast<std::size_t>(*dimension);
  const std::string* sizes_text = field({"sizes"});
  if (sizes_text == nullptr) throw ReadError("NRRD header without sizes");
  const auto size_words = words(*sizes_text);
  if (size_words.size() != ndim) throw ReadError("NRRD sizes do not match its dimension");
  std::vector<std::int64_t> sizes;
  for (auto w : size_words) {
    const auto v = parse_int(w);
    if (!v || *v < 1 || *v > (std::int64_t{1} << 31)) {
      throw ReadError("NRRD sizes must be whole numbers from 1 to 2^31");
    }
    sizes.push_back(*v);
  }

  // Which axis is not spatial: by kinds, else by a "none" space direction, else the first.
  std::vector<bool> spatial(ndim, true);
  std::vector<std::optional<core::Vec3>> directions;
  if (const std::string* d = field({"space directions"})) {
    directions = parse_vectors(*d, "space directions");
    if (directions.size() != ndim)
      throw ReadError("NRRD space directions do not match its dimension");
    for (std::size_t a = 0; a < ndim; ++a) spatial[a] = directions[a].has_value();
  }
  if (const std::string* k = field({"kinds"})) {
    const auto kinds = words(*k);
    if (kinds.size() == ndim && directions.empty()) {
      for (std::size_t a = 0; a < ndim; ++a) {
        const std::string kind = lower(kinds[a]);
        spatial[a] = kind == "domain" || kind == "space" || kind == "time" ? true : false;
      }
    }
  }
  const auto spatial_count =
      static_cast<std::size_t>(std::count(spatial.begin(), spatial.end(), true));
  if (ndim == 4 && spatial_count == 4) spatial[0] = false;  // a list axis first, as Slicer writes
  if (std::count(spatial.begin(), spatial.end(), true) != 3) {
    throw ReadError("NRRD needs three spatial axes (and at most one list axis)");
  }
  std::vector<std::size_t> space_axes;
  for (std::size_t a = 0; a < ndim; ++a) {
    if (spatial[a]) space_axes.push_back(a);
  }
  if (ndim == 4) {
    const std::size_t list_axis = spatial[0] ? 3 : 0;
    if (spatial[list_axis]) {
      throw ReadError("NRRD list axis in the middle of the spatial axes is not supported");
    }
    header.layer_axis_first = list_axis == 0;
    header.layers = static_cast<std::size_t>(sizes[list_axis]);
    if (header.layers > 256) throw ReadError("NRRD list axis longer than 256 layers");
  }
  header.size = {sizes[space_axes[0]], sizes[space_axes[1]], sizes[space_axes[2]]};
  std::uint64_t product = 1;
  for (std::int64_t s : sizes) {
    if (__builtin_mul_overflow(product, static_cast<std::uint64_t>(s), &product) ||
        product > (std::uint64_t{1} << 44)) {
      throw ReadError("NRRD sizes whose product overflows");
    }
  }

  // Geometry.
  std::array<double, 3> flip{1, 1, 1};
  if (const std::string* s = field({"space"})) {
    const std::string space = lower(*s);
    if (auto f = space_to_lps(space)) {
      flip = *f;
    } else if (space == "scanner-xyz" || space == "3d-right-handed" || space == "3d-left-handed") {
      header.warnings.push_back("NRRD space " + space + " has no anatomical meaning: taken as LPS");
    } else {
      throw ReadError("NRRD space is not a 3D anatomical space (LPS, RAS or LAS)");
    }
  } else if (const std::string* sd = field({"space dimension"})) {
    if (parse_int(*sd) != 3) throw ReadError("NRRD space dimension must be 3");
    header.warnings.push_back("NRRD space not named: taken as LPS");
  }
  if (!directions.empty()) {
    for (int a = 0; a < 3; ++a) {
      const core::Vec3& d = *directions[space_axes[static_cast<std::size_t>(a)]];
      for (int c = 0; c < 3; ++c) header.geometry.axes[a][c] = flip[c] * d[c];
    }
  } else if (const std::string* sp = field({"spacings"})) {
    const auto parts = words(*sp);
    if (parts.size() != ndim) throw ReadError("NRRD spacings do not match its dimension");
    for (int a = 0; a < 3; ++a) {
      const auto v = parse_double(parts[space_axes[static_cast<std::size_t>(a)]]);
      if (!v || *v == 0) throw ReadError("NRRD spacing is not a finite non-zero number");
      header.geometry.axes[a] = {0, 0, 0};
      header.geometry.axes[a][a] = std::abs(*v);
    }
    header.warnings.push_back(
        "NRRD without space directions: axes taken along LPS by their spacings");
  } else {
    header.warnings.push_back("NRRD without space directions or spacings: 1 mm voxels along LPS");
  }
  if (const std::string* o = field({"space origin"})) {
    const auto origin = parse_vector(*o, "space origin");
    if (!origin) throw ReadError("NRRD space origin is none");
    for (int c = 0; c < 3; ++c) header.geometry.origin[c] = flip[c] * (*origin)[c];
  }
  const double det = header.geometry.determinant();
  if (!std::isfinite(det) || std::abs(det) < 1e-12) {
    throw ReadError("NRRD space directions are singular (a zero or parallel axis)");
  }

  // Encoding and layout of the samples.
  const std::string* encoding = field({"encoding"});
  if (encoding == nullptr) throw ReadError("NRRD header without an encoding");
  const std::string enc = lower(*encoding);
  if (enc == "raw") {
    header.encoding = Encoding::raw;
  } else if (enc == "gzip" || enc == "gz") {
    header.encoding = Encoding::gzip;
  } else {
    throw ReadError("NRRD encoding " +
                    std::string(enc == "bzip2" || enc == "bz2"                    ? "bzip2"
                                : enc == "ascii" || enc == "text" || enc == "txt" ? "ascii"
                                : enc == "hex"                                    ? "hex"
                                                                                  : "(unknown)") +
                    " is not supported (raw and gzip are)");
  }
  if (const std::string* e = field({"endian"})) {
    const std::string endian = lower(*e);
    if (endian != "little" && endian != "big") throw ReadError("NRRD endian is not little or big");
    header.big_endian = endian == "big";
  } else if (volume_file::sample_bytes(header.type) > 1) {
    header.warnings.push_back("NRRD without endian: little endian assumed");
  }
  if (const std::string* b = field({"byte skip", "byteskip"})) {
    const auto v = parse_int(*b);
    if (!v || *v < -1 || *v > (std::int64_t{1} << 30)) {
      throw ReadError("NRRD byte skip is not -1 or a byte count up to 2^30");
    }
    if (*v == -1 && header.encoding != Encoding::raw) {
      throw ReadError("NRRD byte skip -1 is only valid for raw encoding");
    }
    header.byte_skip = *v;
  }
  if (const std::string* l = field({"line skip", "lineskip"})) {
    const auto v = parse_int(*l);
    if (!v || *v < 0) throw ReadError("NRRD line skip is not a line count");
    header.line_skip = *v;
  }

  // Slicer's segments: index order; label 1 and the index's layer (one layer a segment, the
  // older layout) when the keys are missing.
  for (const auto& [index, keys] : segment_keys) {
    core::Segment segment;
    segment.name = keys.name.value_or("");
    segment.srgb = keys.srgb;
    const std::int64_t layer = keys.layer.value_or(header.layers > 1 ? index : 0);
    const std::int64_t label = keys.label.value_or(header.layers > 1 ? 1 : index + 1);
    if (layer < 0 || static_cast<std::uint64_t>(layer) >= header.layers) {
      throw ReadError("a segment's layer is outside the NRRD's layers");
    }
    if (label < 1 || label > (1 << 24)) throw ReadError("a segment's label value is not 1 to 2^24");
    segment.layer = static_cast<std::size_t>(layer);
    segment.label = static_cast<std::int32_t>(label);
    for (const core::Segment& other : header.segments) {
      if (other.layer == segment.layer && other.label == segment.label) {
        throw ReadError("two segments share a layer and label value");
      }
    }
    header.segments.push_back(std::move(segment));
  }
  return header;
}

}  // namespace typemerge::nrrd
