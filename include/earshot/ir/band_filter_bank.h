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

/** Width, in octaves, of the crossovers between the late reverberation's
 *  band noises (issue 20). With one-octave crossovers (bandWeights) a band's
 *  noise reached to its neighbours' centres, so in a room absorbing in one
 *  band only, the slower neighbours' decays filled that band's octave (T20 at
 *  250 Hz 2.76 s where the band's own was 0.52 s). A third of an octave
 *  leaves each band two thirds of an octave that carries its envelope alone,
 *  and its noise rings for only a few periods of the crossover. Arrivals
 *  (the direct sound, image sources) keep bandWeights: their band gains are
 *  samples of smooth spectra, interpolated over the octave. */
constexpr double kNoiseCrossoverOctaves = 1.0 / 3.0;

/** Weights of the late reverberation's band noises: like bandWeights (they
 *  sum to one, each in [0, 1]) with crossovers kNoiseCrossoverOctaves wide. */
BandArrayD noiseBandWeights(double hz);

}  // namespace earshot
