#include "earshot/dsp/convolver.h"

namespace earshot {

Result<std::unique_ptr<Convolver>> Convolver::create(const ConvolverSettings& settings) {
  auto mixer = ConvolutionMixer::create(settings, 1);
  if (!mixer) return mixer.status();
  return std::unique_ptr<Convolver>(new Convolver(std::move(*mixer)));
}

}  // namespace earshot
