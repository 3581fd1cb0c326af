#include "earshot/dsp/convolver.h"

namespace earshot {

Result<std::unique_ptr<Convolver>> Convolver::create(const ConvolverSettings& settings) {
  auto mixer = ConvolutionMixer::create(settings, 1);
  if (!mixer) return mixer.status();
  // A convolver hears its input from the first call, IR or not.
  EARSHOT_RETURN_IF_ERROR((*mixer)->reserveSource(0));
  return std::unique_ptr<Convolver>(new Convolver(std::move(*mixer)));
}

}  // namespace earshot
