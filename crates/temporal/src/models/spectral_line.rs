//! A voxel's spectral coefficients as the FreMEn models report them.

/// One spectral coefficient `γ = (1/N) Σ_observed (s_i − mean)·e^{−j·2π·t_i/P}` of a voxel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpectralLine {
    /// The model's frequency index (DFT bin, or index into the period list).
    pub frequency: u32,
    /// Period `P` in seconds (infinite for bin 0).
    pub period_seconds: f64,
    /// Real part of `γ`.
    pub re: f64,
    /// Imaginary part of `γ`.
    pub im: f64,
}

impl SpectralLine {
    /// `|γ|`.
    pub fn magnitude(&self) -> f64 {
        self.re.hypot(self.im)
    }
}
