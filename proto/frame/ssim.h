// A perceptual error metric beside the paper's pixel count: the structural similarity index
// (Wang, Bovik, Sheikh & Simoncelli, "Image Quality Assessment: From Error Visibility to
// Structural Similarity", IEEE TIP 13(4), 2004). Copying a pixel that should have changed
// costs little SSIM when it sits in a flat area and much when it breaks an edge.
#pragma once

#include "proto/frame/frame_io.h"

namespace tcfarm {

// Mean SSIM of `test` against `reference`, in [-1, 1], 1 for identical displays. The exact
// choices, so the number can be reproduced:
// - Signal: luma of the displayed image, Y = 0.2126 R' + 0.7152 G' + 0.0722 B' (Rec. 709
//   weights) with R', G', B' = LinearToSrgb8Fast(channel) / 255, so values in [0, 1] and
//   exactly what the PNG shows; dynamic range L = 1.
// - Windows: every 8x8 window that fits inside the image, stride 1, uniform weights (the
//   paper's Section III-C before its Gaussian refinement); in an image narrower or shorter
//   than 8 the window shrinks to the image's width or height.
// - Moments: weighted with weights summing to 1 (population: divide by the window's pixel
//   count), as Wang's reference implementation does.
// - SSIM(x, y) = (2 mu_x mu_y + C1)(2 sigma_xy + C2) / ((mu_x^2 + mu_y^2 + C1)(sigma_x^2 +
//   sigma_y^2 + C2)), C1 = (0.01 L)^2, C2 = (0.03 L)^2; the result is its mean over windows.
// Symmetric in its arguments. Throws std::invalid_argument when the sizes differ or an
// image is empty or malformed.
double Ssim(const Image& reference, const Image& test);

}  // namespace tcfarm
