// Writes small DICOM SEG files with DCMTK's own dcmseg, for the reader's tests and fuzz seeds.
//
// DCMTK 3.6.7 packs binary frames wrongly when rows·columns is not a multiple of 8, so the
// synthetic binary SEGs keep rows·columns a multiple of 8 (the real dcmqi files cover the rest).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace typemerge::test {

struct SynthSegment {
  std::string label;
  std::optional<std::array<std::uint16_t, 3>> cielab;  // DICOM-scaled
};

struct SynthFrame {
  std::uint16_t segment = 1;             // segment number (1-based, file order)
  std::array<double, 3> position{};      // Image Position (Patient), mm
  std::vector<std::uint8_t> pixels;      // rows × columns, row after row: 0/1, or fractional values
};

struct SynthSeg {
  std::uint16_t rows = 4, columns = 6;
  bool fractional = false;
  std::uint16_t max_fractional_value = 255;
  std::array<double, 6> orientation{1, 0, 0, 0, 1, 0};
  std::array<double, 2> pixel_spacing{0.5, 0.75};  // between rows, between columns
  std::optional<double> spacing_between_slices;
  double slice_thickness = 2.0;
  std::vector<SynthSegment> segments;
  std::vector<SynthFrame> frames;
  // Identifying values the reader must never pass on (privacy tests).
  std::string patient_name = "Doe^Jane";
  std::string patient_id = "PID-0042";
  std::string content_creator = "Smith^Operator";
};

// Throws std::runtime_error when DCMTK refuses to write it.
void write_seg(const SynthSeg& seg, const std::filesystem::path& file);

// A pixel pattern: rows × columns, 1 inside the given inclusive box.
std::vector<std::uint8_t> box_pixels(const SynthSeg& seg, int row0, int row1, int col0, int col1,
                                     std::uint8_t value = 1);

}  // namespace typemerge::test
