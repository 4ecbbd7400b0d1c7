//! Adaptive wavelet against film filters at equal total samples (filled in below).
