#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "earshot/materials/material.h"

namespace earshot {
namespace {

// Float storage of values given as doubles: 1e-6 covers float rounding of
// numbers in [0, 1] (float epsilon ~6e-8 relative) with margin.
constexpr float kTol = 1e-6f;

std::string sevenBand(const std::string& materialsBody) {
  return R"({"bands_hz": [125, 250, 500, 1000, 2000, 4000, 8000], "materials": {)" + materialsBody + "}}";
}

TEST(MaterialsParse, AbsorptionOutOfRangeGivesExactOneLineMessage) {
  auto r = parseMaterials(sevenBand(R"("x": {"absorption": [0.1, 0.1, 0.1, 1.7, 0.1, 0.1, 0.1]})"), "file");
  ASSERT_FALSE(r.isOk());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(r.status().message(), "file: material \"x\": absorption[3] = 1.7 is outside [0, 1]");
}

TEST(MaterialsParse, NegativeScatteringAndTransmissionAreRangeErrors) {
  auto s = parseMaterials(sevenBand(R"("wall": {"absorption": [0,0,0,0,0,0,0], "scattering": -0.2})"), "m.json");
  ASSERT_FALSE(s.isOk());
  EXPECT_EQ(s.status().message(), "m.json: material \"wall\": scattering = -0.2 is outside [0, 1]");
  auto t = parseMaterials(
      sevenBand(R"("w": {"absorption": [1,1,1,1,1,1,1], "transmission": [0,0,0,0,0,1.5,0]})"), "m.json");
  ASSERT_FALSE(t.isOk());
  EXPECT_EQ(t.status().message(), "m.json: material \"w\": transmission[5] = 1.5 is outside [0, 1]");
  auto sb = parseMaterials(
      sevenBand(R"("w": {"absorption": [0,0,0,0,0,0,0], "scattering": [0,0,0,0,0,0,2]})"), "m.json");
  ASSERT_FALSE(sb.isOk());
  EXPECT_EQ(sb.status().message(), "m.json: material \"w\": scattering[6] = 2 is outside [0, 1]");
}

TEST(MaterialsParse, OverflowingNumberIsRejected) {
  // JSON has no NaN/Inf literals; 1e400 overflows a double. Either the JSON
  // parser or the finiteness check must refuse it.
  auto r = parseMaterials(sevenBand(R"("x": {"absorption": [0.1, 1e400, 0.1, 0.1, 0.1, 0.1, 0.1]})"), "f");
  ASSERT_FALSE(r.isOk());
  EXPECT_EQ(r.status().message().rfind("f: ", 0), 0u) << r.status().message();
}

TEST(MaterialsParse, TransmissionAboveAbsorptionIsAnError) {
  auto r = parseMaterials(
      sevenBand(R"("glass": {"absorption": [0.1,0.1,0.1,0.1,0.1,0.1,0.1], "transmission": [0,0,0.3,0,0,0,0]})"),
      "g.json");
  ASSERT_FALSE(r.isOk());
  EXPECT_NE(r.status().message().find("g.json: material \"glass\": transmission[2] = 0.3 exceeds absorption[2] = 0.1"),
            std::string::npos)
      << r.status().message();
}

TEST(MaterialsParse, StructuralErrorsNameTheProblem) {
  struct Case {
    std::string json, expected;
  };
  const Case cases[] = {
      {sevenBand(R"("x": {"absorption": [0.1, 0.1]})"), "material \"x\": absorption has 2 values but bands_hz has 7"},
      {sevenBand(R"("x": {"absorption": [0,0,0,0,0,0,0], "absorbtion": 1})"), "material \"x\": unknown key \"absorbtion\""},
      {R"({"bands_hz": [125], "materials": {}, "colour": 1})", "file: unknown key \"colour\""},
      // Names from the file are escaped (core/status.h's quotedName): one line.
      {sevenBand(R"("m\nX": {"absorption": [0,0,0,0,0,0,0], "a\u001b[2J\r": 1})"),
       R"(material "m\nX": unknown key "a\u001b[2J\r")"},
      {sevenBand(R"("": {"absorption": [0,0,0,0,0,0,0]})"), "file: a material has an empty name"},
      {sevenBand(R"("x": {"scattering": 0.1})"), "material \"x\": missing absorption"},
      {sevenBand(R"("x": {"absorption": [0,0,0,"a",0,0,0]})"), "material \"x\": absorption[3] is not a number"},
      {R"({"bands_hz": [125, 500, 250], "materials": {}})", "file: bands_hz[2] = 250 is not above the previous band"},
      {R"({"bands_hz": [0, 500], "materials": {}})", "file: bands_hz[0] = 0 is not a positive frequency"},
      {R"({"materials": {}})", "file: missing bands_hz"},
      {R"({"bands_hz": [125]})", "file: missing materials"},
  };
  for (const auto& c : cases) {
    auto r = parseMaterials(c.json, "file");
    ASSERT_FALSE(r.isOk()) << c.json;
    EXPECT_NE(r.status().message().find(c.expected), std::string::npos) << r.status().message();
    EXPECT_EQ(r.status().message().find_first_of("\n\r"), std::string::npos);
  }
}

TEST(MaterialsParse, MalformedJsonIsOneLineErrorNamingTheFile) {
  auto r = parseMaterials("{\"bands_hz\": [125,\n 250", "broken.json");
  ASSERT_FALSE(r.isOk());
  EXPECT_EQ(r.status().code(), StatusCode::kParseError);
  EXPECT_EQ(r.status().message().rfind("broken.json: malformed JSON", 0), 0u) << r.status().message();
  EXPECT_EQ(r.status().message().find('\n'), std::string::npos);
  // The parser quotes an overflowing number; the message does not.
  auto big = parseMaterials(R"({"materials": {"x": {"absorption": [1e999]}}})", "big.json");
  ASSERT_FALSE(big.isOk());
  EXPECT_EQ(big.status().message(), "big.json: malformed JSON: number overflow parsing");
}

TEST(MaterialsLoad, MissingFileIsNotFoundNamingThePath) {
  auto r = loadMaterials("/nonexistent/dir/mats.json");
  ASSERT_FALSE(r.isOk());
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
  EXPECT_NE(r.status().message().find("/nonexistent/dir/mats.json"), std::string::npos);
}

TEST(MaterialsParse, SevenBandValuesPassThroughAndScalarScatteringFillsAllBands) {
  auto r = parseMaterials(sevenBand(R"("a": {"absorption": [0.01,0.02,0.03,0.04,0.05,0.06,0.07], "scattering": 0.3})"),
                          "f");
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const auto id = r->find("a");
  ASSERT_TRUE(id.has_value());
  EXPECT_EQ(*id, 1u);  // id 0 is the built-in default
  const Material& m = (*r)[*id];
  for (int b = 0; b < kNumBands; ++b) {
    EXPECT_NEAR(m.absorption[b], 0.01f * (b + 1), kTol);
    EXPECT_NEAR(m.scattering[b], 0.3f, kTol);
    EXPECT_EQ(m.transmission[b], 0.0f);
  }
}

// Steam Audio style: 3 bands centred at 400 Hz, 2.5 kHz, 15 kHz.
TEST(MaterialsParse, ThreeBandSteamStyleIsInterpolatedInLogFrequency) {
  auto r = parseMaterials(R"({"bands_hz": [400, 2500, 15000], "materials": {
      "rock": {"absorption": [0.13, 0.20, 0.24], "scattering": [0.1, 0.2, 0.4],
               "transmission": [0.015, 0.002, 0.001]}}})",
                          "steam.json");
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const Material& m = (*r)[*r->find("rock")];
  // Below the first centre: held. 125 and 250 Hz < 400 Hz.
  EXPECT_NEAR(m.absorption[0], 0.13f, kTol);
  EXPECT_NEAR(m.absorption[1], 0.13f, kTol);
  // 1000 Hz is the geometric mean of 400 and 2500 Hz (sqrt(1e6) = 1000), so
  // log-frequency interpolation gives exactly the arithmetic mean.
  EXPECT_NEAR(m.absorption[3], 0.5f * (0.13f + 0.20f), kTol);
  EXPECT_NEAR(m.scattering[3], 0.15f, kTol);
  // 500 Hz: t = ln(500/400) / ln(2500/400).
  const double t500 = std::log(500.0 / 400.0) / std::log(2500.0 / 400.0);
  EXPECT_NEAR(m.absorption[2], 0.13 + t500 * 0.07, kTol);
  // 8 kHz lies between 2.5 and 15 kHz.
  const double t8k = std::log(8000.0 / 2500.0) / std::log(15000.0 / 2500.0);
  EXPECT_NEAR(m.absorption[6], 0.20 + t8k * 0.04, kTol);
  EXPECT_NEAR(m.transmission[6], 0.002 + t8k * (0.001 - 0.002), kTol);
  // Interpolation keeps tau <= alpha band by band (both are convex mixes).
  for (int b = 0; b < kNumBands; ++b) EXPECT_LE(m.transmission[b], m.absorption[b]);
}

// Resonance Audio style: 9 octave bands 31.25 Hz .. 8 kHz.
TEST(MaterialsParse, NineBandResonanceStyleKeepsTheMatchingBands) {
  auto r = parseMaterials(R"({"bands_hz": [31.25, 62.5, 125, 250, 500, 1000, 2000, 4000, 8000], "materials": {
      "curtain-heavy": {"absorption": [0.073, 0.106, 0.14, 0.35, 0.55, 0.72, 0.7, 0.65, 1.0]}}})",
                          "ra.json");
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const Material& m = (*r)[*r->find("curtain-heavy")];
  const float expected[kNumBands] = {0.14f, 0.35f, 0.55f, 0.72f, 0.7f, 0.65f, 1.0f};
  for (int b = 0; b < kNumBands; ++b) EXPECT_NEAR(m.absorption[b], expected[b], kTol) << b;
  EXPECT_NEAR(m.scattering[0], 0.1f, kTol);  // documented default when absent
}

TEST(MaterialsParse, SingleBandIsHeldEverywhere) {
  BandArray a = interpolateToEngineBands({1000.0}, {0.42});
  for (float v : a) EXPECT_NEAR(v, 0.42f, kTol);
  BandArray bad = interpolateToEngineBands({500.0, 250.0}, {0.1, 0.2});  // not ascending
  for (float v : bad) EXPECT_EQ(v, 0.0f);
}

TEST(MaterialTable, DefaultIsIdZeroAndAddReplacesByName) {
  MaterialTable t;
  ASSERT_EQ(t.size(), 1u);
  EXPECT_EQ(t[0].name, "default");
  Material a;
  a.name = "a";
  a.absorption = filledBands(0.3f);
  EXPECT_EQ(t.add(a), 1u);
  a.absorption = filledBands(0.6f);
  EXPECT_EQ(t.add(a), 1u);  // replaced, not appended
  EXPECT_EQ(t.size(), 2u);
  EXPECT_FLOAT_EQ(t[1].absorption[0], 0.6f);
  ASSERT_TRUE(t.setDefault("a").isOk());
  EXPECT_FLOAT_EQ(t[0].absorption[0], 0.6f);
  EXPECT_FALSE(t.setDefault("missing").isOk());
}

TEST(MaterialsParse, MaterialNamedDefaultTakesIdZero) {
  auto r = parseMaterials(sevenBand(R"("wall": {"absorption": [0,0,0,0,0,0,0]},
                                      "default": {"absorption": [0.5,0.5,0.5,0.5,0.5,0.5,0.5]})"),
                          "f");
  ASSERT_TRUE(r.isOk());
  EXPECT_EQ(r->size(), 2u);
  EXPECT_EQ(*r->find("default"), 0u);
  EXPECT_FLOAT_EQ((*r)[0].absorption[3], 0.5f);
  EXPECT_EQ(*r->find("wall"), 1u);
}

TEST(DefaultMaterials, HasAtLeast25ValidMaterialsIncludingTheCommonOnes) {
  const MaterialTable& t = defaultMaterials();
  EXPECT_GE(t.size(), 26u);  // 25 materials plus "default"
  EXPECT_EQ(t[0].name, "default");
  for (const Material& m : t.all()) {
    EXPECT_FALSE(m.name.empty());
    for (int b = 0; b < kNumBands; ++b) {
      EXPECT_TRUE(m.absorption[b] >= 0.0f && m.absorption[b] <= 1.0f) << m.name;
      EXPECT_TRUE(m.scattering[b] >= 0.0f && m.scattering[b] <= 1.0f) << m.name;
      EXPECT_TRUE(m.transmission[b] >= 0.0f && m.transmission[b] <= m.absorption[b]) << m.name;
    }
  }
  for (const char* name : {"concrete", "brick", "plaster", "gypsum_board", "wood_panel", "wood_floor", "glass_window",
                           "glass_heavy", "carpet_thin", "carpet_thick", "curtain_light", "curtain_heavy",
                           "acoustic_ceiling_tile", "rockwool", "audience", "seats_upholstered", "water", "grass",
                           "soil", "gravel", "metal", "marble", "ceramic_tile", "linoleum", "foam", "door_wood"})
    EXPECT_TRUE(t.find(name).has_value()) << name;
  // Thin partitions, glass and doors transmit something; massive walls do not.
  EXPECT_GT(t[*t.find("door_wood")].transmission[0], 0.0f);
  EXPECT_GT(t[*t.find("glass_window")].transmission[0], 0.0f);
  EXPECT_EQ(t[*t.find("concrete")].transmission[0], 0.0f);
}

TEST(DefaultMaterials, CompiledInSetEqualsTheShippedFile) {
  auto file = loadMaterials(std::string(EARSHOT_SOURCE_DIR) + "/materials/default.json");
  ASSERT_TRUE(file.isOk()) << file.status().message();
  const MaterialTable& builtIn = defaultMaterials();
  ASSERT_EQ(file->size(), builtIn.size());
  for (size_t i = 0; i < builtIn.size(); ++i) {
    EXPECT_EQ((*file)[i].name, builtIn[i].name);
    EXPECT_EQ((*file)[i].absorption, builtIn[i].absorption);
  }
}

}  // namespace
}  // namespace earshot
