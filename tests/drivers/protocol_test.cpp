#include "mtcal/drivers/interferometer/protocol.h"

#include <gtest/gtest.h>

#include "mtcal/drivers/crc.h"
#include "mtcal/error.h"

namespace mtcal::drivers::interferometer {
namespace {

using Bytes = std::vector<std::uint8_t>;

// The expected frames below were computed by an independent implementation of the framing
// (a few lines of Python) and are written out as literals.

TEST(Crc16, CcittFalseCheckValue) {
  // CRC catalogue (Williams / reveng) check value of CRC-16/CCITT-FALSE for "123456789".
  const std::string text = "123456789";
  EXPECT_EQ(crc16Ccitt({reinterpret_cast<const std::uint8_t*>(text.data()), text.size()}), 0x29B1);
}

TEST(Protocol, EncodesHostCommandsAsDocumented) {
  EXPECT_EQ(encodeIdentify(), (Bytes{0xA5, 0x5A, 0x01, 0x00, 0x00, 0xAC, 0xFB}));
  EXPECT_EQ(encodeStartStream(1000), (Bytes{0xA5, 0x5A, 0x03, 0x04, 0x00, 0xE8, 0x03, 0x00, 0x00, 0x94, 0x77}));
  EXPECT_EQ(encodeAck(MessageType::kStartStream), (Bytes{0xA5, 0x5A, 0x80, 0x01, 0x00, 0x03, 0xAB, 0x5E}));
}

TEST(Protocol, DecodesADataFrameFromBytes) {
  const Bytes wire = {0xa5, 0x5a, 0x90, 0x24, 0x00, 0x07, 0x00, 0x00, 0x00, 0x40, 0x42, 0x0f, 0x00, 0x00, 0x00,
                      0x00, 0x00, 0xe8, 0x03, 0x00, 0x00, 0x02, 0x00, 0x15, 0xcd, 0x5b, 0x07, 0x00, 0x00, 0x00,
                      0x00, 0xd5, 0xfb, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x00, 0x75, 0x06};
  FrameDecoder decoder;
  decoder.feed(wire);
  auto frame = decoder.next();
  ASSERT_TRUE(frame);
  const DataBlock block = parseData(*frame);
  EXPECT_EQ(block.first_seq, 7u);
  EXPECT_EQ(block.first_time_ns, 1'000'000u);
  EXPECT_EQ(block.period_ns, 1000u);
  ASSERT_EQ(block.samples.size(), 2u);
  EXPECT_EQ(block.samples[0].value, 123456789);
  EXPECT_TRUE(block.samples[0].beam_ok);
  EXPECT_EQ(block.samples[0].signal_pct, 85);
  EXPECT_EQ(block.samples[1].value, -5);
  EXPECT_FALSE(block.samples[1].beam_ok);
  // And the encoder produces exactly these bytes.
  EXPECT_EQ(encodeData(block), wire);
}

TEST(Protocol, DecodesAnEnvironmentFrameFromBytes) {
  const Bytes wire = {0xa5, 0x5a, 0x85, 0x10, 0x00, 0x14, 0x50, 0x00, 0x00, 0x02, 0x76, 0x0f,
                      0x00, 0xc6, 0x11, 0x07, 0x01, 0x9d, 0x4e, 0x00, 0x00, 0x14, 0x07};
  FrameDecoder decoder;
  decoder.feed(wire);
  const Environment env = parseEnvironment(*decoder.next());
  EXPECT_DOUBLE_EQ(env.air_temp_c, 20.5);
  EXPECT_DOUBLE_EQ(env.air_pressure_pa, 101325.0);
  EXPECT_DOUBLE_EQ(env.humidity_pct, 45.5);
  EXPECT_TRUE(env.air_temp_ok && env.pressure_ok && env.humidity_ok);
  ASSERT_EQ(env.material_temps_c.size(), 1u);
  EXPECT_DOUBLE_EQ(env.material_temps_c[0], 20.125);
}

TEST(Protocol, RoundTripsEveryDeviceMessage) {
  FrameDecoder decoder;
  const Identity id{1, 632.990577, "MODEL", "SN42", "2.1"};
  decoder.feed(encodeIdentity(id));
  const Identity back = parseIdentity(*decoder.next());
  EXPECT_EQ(back.serial, "SN42");
  EXPECT_DOUBLE_EQ(back.vacuum_wavelength_nm, 632.990577);
  decoder.feed(encodeNak({MessageType::kStartStream, NakCode::kBeamLost, "beam"}));
  const Nak nak = parseNak(*decoder.next());
  EXPECT_EQ(nak.code, NakCode::kBeamLost);
  EXPECT_EQ(nak.text, "beam");
  decoder.feed(encodeSetOptics(Optics::kAngular));
  EXPECT_EQ(parseSetOptics(*decoder.next()), Optics::kAngular);
}

TEST(FrameDecoder, ReassemblesFramesSplitAtEveryByte) {
  Bytes stream;
  for (int i = 0; i < 3; ++i) {
    const auto f = encodeStartStream(100 + i);
    stream.insert(stream.end(), f.begin(), f.end());
  }
  FrameDecoder decoder;
  std::vector<std::uint32_t> rates;
  for (std::uint8_t b : stream) {
    decoder.feed(std::span(&b, 1));
    while (auto f = decoder.next()) rates.push_back(parseStartStream(*f));
  }
  EXPECT_EQ(rates, (std::vector<std::uint32_t>{100, 101, 102}));
  EXPECT_EQ(decoder.crcErrors(), 0u);
  EXPECT_EQ(decoder.buffered(), 0u);
}

TEST(FrameDecoder, SkipsGarbageAndCorruptFramesAndCountsThem) {
  Bytes stream = {0x00, 0xA5, 0x13, 0x5A};  // garbage, including a lone sync byte
  auto good1 = encodeStartStream(1);
  auto bad = encodeStartStream(2);
  bad[6] ^= 0xFF;  // payload corrupted: CRC mismatch
  auto good2 = encodeStartStream(3);
  for (const auto* f : {&good1, &bad, &good2}) stream.insert(stream.end(), f->begin(), f->end());
  FrameDecoder decoder;
  decoder.feed(stream);
  std::vector<std::uint32_t> rates;
  while (auto f = decoder.next()) rates.push_back(parseStartStream(*f));
  EXPECT_EQ(rates, (std::vector<std::uint32_t>{1, 3}));
  EXPECT_GE(decoder.crcErrors(), 1u);
  EXPECT_GE(decoder.discardedBytes(), 4u + bad.size() - 1);
}

TEST(FrameDecoder, ResynchronisesAfterAnImpossibleLength) {
  Bytes stream = {0xA5, 0x5A, 0x90, 0xFF, 0xFF};  // 65535-byte payload cannot exist
  const auto good = encodeIdentify();
  stream.insert(stream.end(), good.begin(), good.end());
  FrameDecoder decoder;
  decoder.feed(stream);
  auto f = decoder.next();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->type, MessageType::kIdentify);
}

TEST(Protocol, MalformedPayloadsNameTheMessageAndTheDefect) {
  Frame short_data{MessageType::kData, {1, 2, 3}};
  try {
    parseData(short_data);
    FAIL();
  } catch (const ProtocolError& e) {
    EXPECT_NE(std::string(e.what()).find("DATA"), std::string::npos) << e.what();
  }
  // DATA announcing more samples than it carries.
  DataBlock block;
  block.samples.resize(2);
  FrameDecoder d;
  auto wire = encodeData(block);
  Frame f{MessageType::kData, Bytes(wire.begin() + 5, wire.end() - 2)};
  f.payload.pop_back();
  EXPECT_THROW(parseData(f), ProtocolError);
  EXPECT_THROW(parseAck(Frame{MessageType::kNak, {}}), ProtocolError);  // wrong type
  EXPECT_THROW(parseEnvironment(Frame{MessageType::kEnvironment, Bytes(11, 0)}), ProtocolError);
  Bytes env(11, 0);
  env[10] = 4;  // four material sensors announced
  EXPECT_THROW(parseEnvironment(Frame{MessageType::kEnvironment, env}), ProtocolError);
  EXPECT_THROW(parseSetOptics(Frame{MessageType::kSetOptics, {9}}), ProtocolError);
  DataBlock too_big;
  too_big.samples.resize(kMaxSamplesPerFrame + 1);
  EXPECT_THROW(encodeData(too_big), ProtocolError);
}

}  // namespace
}  // namespace mtcal::drivers::interferometer
