#pragma once
/** @file Zero-phase octave-band weights that sum to exactly one at every
 *  frequency, so bands recombine flat (a perfect-reconstruction filter bank
 *  in the frequency domain).
 *
 *  Band b's weight is S_{b-1}(f) - S_b(f), where S_k is a raised-cosine step
 *  on log2(f) centred on the crossover between bands k and k+1 (the geometric
 *  mean of their centres), one octave wide, with S_{-1} = 1 and S_6 = 0. The
 *  sum telescopes to 1; neighbouring transitions do not overlap, so each
 *  weight lies in [0, 1]. */
#include "earshot/core/bands.h"

namespace earshot {

/** Weight of band `band` (0..kNumBands-1) at frequency `hz` (>= 0). */
double bandWeight(int band, double hz);

/** All weights at `hz`. */
BandArrayD bandWeights(double hz);

}  // namespace earshot
