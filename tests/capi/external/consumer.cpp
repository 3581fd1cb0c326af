// Uses an installed earshot from C++ (earshot.hpp): a source in free field,
// simulated once, must be heard. Prints "ok" and exits 0.
#include <cmath>
#include <cstdio>
#include <exception>
#include <vector>

#include "earshot/earshot.hpp"

int main() {
  try {
    earshot::ContextSettings settings;
    settings.max_sources = 1;
    settings.max_ir_seconds = 0.5;
    earshot::Context context(settings);
    earshot::Source source(context);
    source.setPosition(earshot::vec3(1, 0, -2));
    context.simulate();
    std::vector<float> dry(2048, 0.0f), left(2048), right(2048);
    dry[0] = 1.0f;
    const float* inputs[1] = {dry.data()};
    if (context.process(inputs, left.data(), right.data(), dry.size()) != EARSHOT_OK) return 1;
    double e = 0;
    for (size_t i = 0; i < left.size(); ++i) e += double(left[i]) * left[i] + double(right[i]) * right[i];
    if (!(e > 0) || !std::isfinite(e)) return 1;
    std::printf("ok\n");
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
}
