#include "earshot/io/wav.h"

#include <sndfile.h>

#include <unistd.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <memory>

#include "earshot/io/atomic_file.h"
#include "earshot/io/input_file.h"

namespace earshot {

namespace {
struct SndCloser {
  void operator()(SNDFILE* f) const { sf_close(f); }
};
using SndPtr = std::unique_ptr<SNDFILE, SndCloser>;
}  // namespace

size_t defaultMaxReadSamples() {
  return static_cast<size_t>(defaultInputLimits().maxMemoryBytes / (16 * sizeof(float)));
}

Result<AudioBuffer> readAudioFile(const std::string& path, size_t maxSamples) {
  if (maxSamples == 0) maxSamples = defaultMaxReadSamples();
  // A regular file only (never a FIFO or device: libsndfile would block or
  // read forever); any size, since what counts is what it decodes to.
  auto checked = checkInputFile(path, "audio file", UINT64_MAX);
  if (!checked) return checked.status();
  SF_INFO info{};
  SndPtr f(sf_open(path.c_str(), SFM_READ, &info));
  if (!f) return ioError(path + ": cannot read audio (" + sf_strerror(nullptr) + ")");
  if (info.channels <= 0 || info.samplerate <= 0)
    return parseError(path + ": invalid header (channels " + std::to_string(info.channels) + ", rate " +
                      std::to_string(info.samplerate) + ")");
  if (info.frames < 0 || double(info.frames) * info.channels > double(maxSamples))
    return outOfRange(path + ": header claims " + std::to_string(info.frames) + " frames x " +
                      std::to_string(info.channels) + " channels, over the limit of " +
                      std::to_string(maxSamples) + " samples");
  // Read in blocks and keep what arrives: a header may claim far more frames
  // than the file holds, and must not make us allocate them.
  const size_t ch = size_t(info.channels);
  constexpr size_t kBlockFrames = 65536;
  std::vector<float> block(kBlockFrames * ch);
  AudioBuffer out(ch, 0, double(info.samplerate));
  for (;;) {
    const sf_count_t got = sf_readf_float(f.get(), block.data(), sf_count_t(kBlockFrames));
    if (got < 0) return ioError(path + ": read failed");
    if (got == 0) break;
    const size_t start = out.frameCount();
    if ((start + size_t(got)) * ch > maxSamples)
      return outOfRange(path + ": more than " + std::to_string(maxSamples) + " samples, over the limit");
    for (size_t c = 0; c < ch; ++c) out.channels[c].resize(start + size_t(got));
    for (size_t i = 0; i < size_t(got); ++i)
      for (size_t c = 0; c < ch; ++c) {
        const float v = block[i * ch + c];
        if (!std::isfinite(v))
          return parseError(path + ": sample " + std::to_string(start + i) + " of channel " + std::to_string(c) +
                            " is not finite");
        out.channels[c][start + i] = v;
      }
    if (size_t(got) < kBlockFrames) break;
  }
  return out;
}

Result<AudioFileFormat> audioFormatForPath(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  const std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
  const size_t dot = name.find_last_of('.');
  std::string ext = dot == std::string::npos || dot == 0 ? "" : name.substr(dot + 1);
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext.empty() || ext == "wav" || ext == "wave") return AudioFileFormat{SF_FORMAT_WAV | SF_FORMAT_FLOAT, false, "WAV, 32-bit float"};
  if (ext == "flac") return AudioFileFormat{SF_FORMAT_FLAC | SF_FORMAT_PCM_24, true, "FLAC, 24-bit"};
  if (ext == "ogg" || ext == "oga") return AudioFileFormat{SF_FORMAT_OGG | SF_FORMAT_VORBIS, true, "Ogg Vorbis"};
  return unsupported(path + ": '." + ext.substr(0, 16) +
                     "' names no format earshot writes: .wav (32-bit float), .flac (24-bit) or .ogg (Vorbis)");
}

namespace {

/** Opens `tmp` for writing in `format` (no PEAK chunk: it carries a
 *  timestamp, and identical audio must give identical files); fixed-point
 *  formats clip beyond full scale instead of wrapping. */
SNDFILE* openForWriting(const std::string& tmp, const AudioFileFormat& format, size_t channels, double rate) {
  SF_INFO info{};
  info.channels = int(channels);
  info.samplerate = int(std::lround(rate));
  info.format = format.sndfileFormat;
  SNDFILE* f = sf_open(tmp.c_str(), SFM_WRITE, &info);
  if (!f) return nullptr;
  sf_command(f, SFC_SET_ADD_PEAK_CHUNK, nullptr, SF_FALSE);
  if (format.clipsAtFullScale) sf_command(f, SFC_SET_CLIPPING, nullptr, SF_TRUE);
  return f;
}

}  // namespace

Status writeInFormat(const std::string& path, const AudioBuffer& audio, const AudioFileFormat& format,
                     uint64_t* clippedSamples);

Status writeWavFloat(const std::string& path, const AudioBuffer& audio) {
  return writeInFormat(path, audio, AudioFileFormat{SF_FORMAT_WAV | SF_FORMAT_FLOAT, false, "WAV, 32-bit float"},
                       nullptr);
}

Status writeAudioFile(const std::string& path, const AudioBuffer& audio, uint64_t* clippedSamples) {
  if (clippedSamples) *clippedSamples = 0;
  auto format = audioFormatForPath(path);
  if (!format.isOk()) return format.status();
  return writeInFormat(path, audio, *format, clippedSamples);
}

Status writeInFormat(const std::string& path, const AudioBuffer& audio, const AudioFileFormat& fmt,
                     uint64_t* clippedSamples) {
  const AudioFileFormat* format = &fmt;
  const size_t ch = audio.channelCount(), frames = audio.frameCount();
  if (ch == 0) return invalidArgument(path + ": no channels to write");
  if (!(audio.sampleRateHz >= 1.0 && audio.sampleRateHz <= 1e6))
    return invalidArgument(path + ": sample rate " + std::to_string(audio.sampleRateHz) + " is outside [1, 1e6] Hz");
  for (size_t c = 0; c < ch; ++c) {
    if (audio.channels[c].size() != frames) return invalidArgument(path + ": channels differ in length");
    for (size_t i = 0; i < frames; ++i)
      if (!std::isfinite(audio.channels[c][i]))
        return invalidArgument(path + ": sample " + std::to_string(i) + " of channel " + std::to_string(c) +
                               " is not finite; nothing written");
  }
  if (format->clipsAtFullScale && clippedSamples)
    for (const auto& c : audio.channels)
      for (float v : c) *clippedSamples += std::fabs(v) > 1.0f ? 1 : 0;
  return writeFileAtomically(path, [&](const std::string& tmp) -> Status {
    SndPtr f(openForWriting(tmp, *format, ch, audio.sampleRateHz));
    if (!f) return ioError(path + ": cannot open for writing (" + sf_strerror(nullptr) + ")");
    std::vector<float> block(4096 * ch);
    for (size_t start = 0; start < frames; start += 4096) {
      size_t n = std::min<size_t>(4096, frames - start);
      for (size_t i = 0; i < n; ++i)
        for (size_t c = 0; c < ch; ++c) block[i * ch + c] = audio.channels[c][start + i];
      if (sf_writef_float(f.get(), block.data(), sf_count_t(n)) != sf_count_t(n))
        return ioError(path + ": write failed");
    }
    if (sf_close(f.release()) != 0) return ioError(path + ": close failed");
    return Status::ok();
  });
}

Result<std::unique_ptr<WavStreamWriter>> WavStreamWriter::open(const std::string& path, size_t channels,
                                                                double sampleRateHz) {
  if (channels == 0 || channels > 64) return invalidArgument(path + ": " + std::to_string(channels) + " channels");
  if (!(sampleRateHz >= 1.0 && sampleRateHz <= 1e6))
    return invalidArgument(path + ": sample rate " + std::to_string(sampleRateHz) + " is outside [1, 1e6] Hz");
  auto format = audioFormatForPath(path);
  if (!format.isOk()) return format.status();
  EARSHOT_RETURN_IF_ERROR(checkOutputPath(path));
  std::unique_ptr<WavStreamWriter> w(new WavStreamWriter());
  w->mFormat = *format;
  w->mPath = path;
  w->mTmp = path + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(reinterpret_cast<uintptr_t>(w.get()));
  w->mChannels = channels;
  w->mTmpGuard = std::make_unique<TempFileGuard>(w->mTmp);
  SNDFILE* f = openForWriting(w->mTmp, *format, channels, sampleRateHz);
  if (!f) return ioError(path + ": cannot open for writing (" + sf_strerror(nullptr) + ")");
  w->mFile = f;
  return w;
}

WavStreamWriter::~WavStreamWriter() {
  if (mFile) {
    sf_close(static_cast<SNDFILE*>(mFile));
    std::remove(mTmp.c_str());
  }
}

Status WavStreamWriter::write(const float* const* planar, size_t frames) {
  if (!mFile) return ioError(mPath + ": already committed");
  if (!mFormat.clipsAtFullScale && (mFrames + frames) * mChannels * sizeof(float) > kMaxWavBytes)
    return outOfRange(mPath + ": over the 4 GiB a WAV file can hold");
  mInterleaved.resize(frames * mChannels);
  for (size_t i = 0; i < frames; ++i)
    for (size_t c = 0; c < mChannels; ++c) {
      const float v = planar[c][i];
      if (!std::isfinite(v))
        return invalidArgument(mPath + ": sample " + std::to_string(mFrames + i) + " of channel " + std::to_string(c) +
                               " is not finite; nothing written");
      mInterleaved[i * mChannels + c] = v;
      mClipped += mFormat.clipsAtFullScale && std::fabs(v) > 1.0f ? 1 : 0;
    }
  if (sf_writef_float(static_cast<SNDFILE*>(mFile), mInterleaved.data(), sf_count_t(frames)) != sf_count_t(frames))
    return ioError(mPath + ": write failed (" + sf_strerror(static_cast<SNDFILE*>(mFile)) + ")");
  mFrames += frames;
  return Status::ok();
}

Status WavStreamWriter::commit() {
  if (!mFile) return ioError(mPath + ": already committed");
  const int closed = sf_close(static_cast<SNDFILE*>(mFile));
  mFile = nullptr;
  if (closed != 0) {
    std::remove(mTmp.c_str());
    return ioError(mPath + ": close failed");
  }
  Status s = checkOutputPath(mPath);  // the target may have changed meanwhile
  if (s.isOk() && std::rename(mTmp.c_str(), mPath.c_str()) != 0) s = ioError(mPath + ": cannot write (rename failed)");
  if (!s.isOk()) std::remove(mTmp.c_str());
  mTmpGuard.reset();
  return s;
}

Status appendScaled(const std::string& path, float gain, WavStreamWriter& out) {
  SF_INFO info{};
  SndPtr f(sf_open(path.c_str(), SFM_READ, &info));
  if (!f) return ioError(path + ": cannot read audio (" + sf_strerror(nullptr) + ")");
  if (size_t(info.channels) != out.channels())
    return invalidArgument(path + ": " + std::to_string(info.channels) + " channels, the output has " +
                           std::to_string(out.channels()));
  constexpr size_t kBlock = 4096;
  const size_t ch = out.channels();
  std::vector<float> interleaved(kBlock * ch);
  std::vector<std::vector<float>> planar(ch, std::vector<float>(kBlock));
  std::vector<const float*> ptrs(ch);
  for (size_t c = 0; c < ch; ++c) ptrs[c] = planar[c].data();
  for (;;) {
    const sf_count_t got = sf_readf_float(f.get(), interleaved.data(), sf_count_t(kBlock));
    if (got <= 0) break;
    for (sf_count_t i = 0; i < got; ++i)
      for (size_t c = 0; c < ch; ++c) planar[c][size_t(i)] = interleaved[size_t(i) * ch + c] * gain;
    EARSHOT_RETURN_IF_ERROR(out.write(ptrs.data(), size_t(got)));
    if (size_t(got) < kBlock) break;
  }
  return Status::ok();
}

}  // namespace earshot
