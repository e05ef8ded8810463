//! Temporal models of voxel occupancy for froctomap: FreMEn, a two-state Markov chain and a
//! static baseline, behind one plugin trait, with lossless outlier sets.
//!
//! # The method
//!
//! FROctomap (Krajník et al., 2014) stores a series of occupancy maps as one model per voxel.
//! Each voxel's binary state `s(t)` is summarised by FreMEn (Frequency Map Enhancement): its
//! mean `μ` plus the `n` strongest spectral components of `s − μ`,
//!
//! ```text
//! γ(P) = (1/N) Σ_observed (s_i − μ) · e^{−j·2π·t_i/P}          (N = observed samples)
//! p(t) = μ + Σ_{kept P} A_P · cos(2π·t/P + φ_P),   A_P = 2|γ(P)|,  φ_P = arg γ(P)
//! ```
//!
//! clamped to `[0, 1]`. `p(t)` is a probability usable at *any* time, including the future,
//! which is what makes the model useful for prediction. To make it exact, the *outlier set*
//! stores where the thresholded model `p(t) > 0.5` disagrees with the observations, as sorted
//! toggle positions: `s(i) = (p(i) > 0.5) XOR (parity of toggles ≤ i)` ([`Toggles`]). Keeping
//! it is lossless ([`OutlierMode::Lossless`]); dropping it is lossy and tiny, and each voxel
//! reports its reconstruction error ([`FittedVoxel::model_errors`],
//! [`PreparedModel::reconstruction_error`]).
//!
//! # What differs from the published implementation, and why
//!
//! - **Unknown is not free.** A voxel is fitted from the samples where it was observed
//!   ([`VoxelObservations`], runs of known state); gaps do not enter the sums or the mean, and
//!   toggles may sit anywhere in a gap, which gives the fewest toggles possible.
//! - **Real time, not frame numbers.** [`models::FremenPeriods`] works on any
//!   [`TimeAxis`] (jittered or missed snapshots) at a candidate period set (one week / k,
//!   k ≤ 48, plus user periods); a period is used only once the observed samples cover
//!   `min_cycles` (2) whole cycles of it (first to last plus one step), and never beside a stronger chosen period it aliases (closer than `1/span` in
//!   frequency, directly or through the sampling grid).
//!   [`models::FremenRegular`] keeps the FFT formulation for regular grids, over *all* DFT
//!   bins instead of the first 99.
//! - **Compact, exact, portable outliers.** Toggles are delta + LEB128 varint encoded in
//!   sample units ([`varint`]), not absolute `u32`s. The encoder thresholds `p` computed from
//!   the *quantised* parameters with a deterministic cos/sin ([`trig`]), exactly as a decoder
//!   on any machine will, so lossless means bit-exact everywhere.
//! - **Model order per voxel.** [`Order::Fixed`] or [`Order::Auto`]: the best held-out
//!   prediction (default, also in lossless files) or the smallest encoded voxel
//!   ([`OrderCriterion`]); see [`Order`]. Options `order`, `max-order`, `criterion`.
//! - **Prediction validated on held-out data, not only fitted.** The held-out part is half
//!   a voxel's samples when the fit half keeps every period; where it spans whole cycles of
//!   an order's periods, the amplitudes may be shrunk (`shrink`), orders above 5 compete, and
//!   an order's crossings of 0.5 must beat the mean's decisions significantly (a sign test)
//!   or be shrunk away. The stored parameters are this prediction model; lossless files stay
//!   exact through their outliers.
//!
//! # Plugins
//!
//! A [`TemporalModel`] is selected by a stable [`ModelId`] recorded in files, resolved through
//! a [`ModelRegistry`] of [`ModelDescriptor`]s (id, name, description, [`OptionDescriptor`]s,
//! factory). A [`ModelConfig`] is the outlier mode plus the model's own options as
//! `key=value` text ([`ModelOptions`]), which the model parses and validates. `prepare` does
//! the per-axis work shared by all voxels of a map (unit-root tables and FFT plan, prefix
//! sums of cos/sin per period) and returns a [`PreparedModel`] that fits voxels and
//! evaluates them. Model-global parameters (e.g. the period list) are written once with
//! [`PreparedModel::encode_parameters`] and read back with
//! [`TemporalModel::prepare_from_parameters`].
//!
//! A voxel's parameters are bytes the model owns ([`FittedVoxel::parameters`]): containers
//! store them verbatim, delimit (and validate) them with [`PreparedModel::parameters_len`],
//! and evaluate them in place ([`PreparedModel::probability`],
//! [`PreparedModel::probability_at_sample`], [`PreparedModel::mean`], …) without decoding.
//!
//! | id | name | voxel parameters | parameters after the header | options |
//! |---|---|---|---|---|
//! | 0 | `static` | spectral, no components | — | — |
//! | 1 | `fremen-regular` | spectral, frequency = DFT bin `k`, period `len·step/k` | — | `order`, `max-order`, `criterion`, `min-cycles`, `holdout-fraction` |
//! | 2 | `fremen-periods` | spectral, frequency = index into the period list | `varint K`, `K × f64 LE` seconds | the above plus `periods`, `base-period`, `harmonics` |
//! | 3 | `markov` | `u16 LE` π, varint `2·last sample + last state`, `f32 LE` rate λ ([`models::markov`]) | — | — |
//!
//! Parameter header (all models): `u8 version = 1`, `u8 outlier mode` (0 lossless, 1 lossy).
//!
//! # Voxel encoding
//!
//! A voxel is its parameters, then (lossless only) its toggles: varint count, then varint
//! `first`, varint `next − previous − 1`, … ([`Toggles::encode`]). The spectral parameters
//! of models 0-2 ([`SpectralParameters`]):
//!
//! | field | encoding |
//! |---|---|
//! | mean | `u16 LE`, `μ = q / 65535` |
//! | component count `m` | varint (≤ 255) |
//! | `m ×` frequency | varint (meaning per model, see above) |
//! | `m ×` amplitude, phase | `u16 LE` each: `A = q / 65535`, `φ = 2π·q / 65536` |
//!
//! Components are stored strongest first and `p` is summed in stored order, so the first `m'`
//! components are the order-`m'` model. Quantisation moves `p` by at most
//! `7.7e-6 + Σ_c (7.7e-6 + 4.8e-5·A_c)` (see [`Component`]); it never affects exactness,
//! since outliers are computed from the quantised values.
//!
//! # Example
//!
//! ```
//! use froctomap_core::{Occupancy, Timestamp};
//! use froctomap_temporal::*;
//! // One voxel observed every 10 minutes for three weeks, occupied from 8:00 to 18:00 on
//! // weekdays, with a sensor outage on day 3.
//! let step = 600_000_000_000; // 10 minutes
//! let axis = TimeAxis::regular(Timestamp::from_secs(0), step, 3 * 7 * 144, vec![])?;
//! let mut b = ObservationsBuilder::new();
//! for i in 0..axis.len() {
//!     let (day, slot) = (i / 144, i % 144);
//!     let state = (day % 7 < 5 && (48..108).contains(&slot)) ^ (i % 97 == 0); // with noise
//!     let known = day != 3;
//!     b.push(i, known.then_some(Occupancy::from(state)))?;
//! }
//! let obs = b.finish();
//!
//! let registry = ModelRegistry::with_default_models();
//! let model = registry.by_name("fremen-periods").unwrap().create();
//! let prepared = model.prepare(&axis, &ModelConfig::default().with_option("order", 5))?;
//! let voxel = prepared.fit(&obs)?;
//!
//! // Encode, then decode as a reader would from the file header and voxel bytes.
//! let mut bytes = Vec::new();
//! prepared.encode_voxel(&voxel, &mut bytes);
//! let reader = registry.prepare_from_parameters(model.id(), &axis, &prepared.encode_parameters())?;
//! let (decoded, used) = reader.decode_voxel(&bytes)?;
//! assert_eq!((decoded.clone(), used), (voxel, bytes.len()));
//! for (i, s) in obs.iter() {
//!     assert_eq!(reader.state_at_sample(&decoded, i), s); // lossless
//! }
//! // Prediction: next Monday 12:00 is likely occupied, next Sunday 12:00 is not.
//! let monday_noon = (21.0 * 86_400.0) + 12.0 * 3600.0;
//! assert!(reader.probability(decoded.parameters(), monday_noon) > 0.5);
//! assert!(reader.probability(decoded.parameters(), monday_noon + 6.0 * 86_400.0) < 0.5);
//! # Ok::<(), TemporalError>(())
//! ```

mod axis;
mod error;
mod fit;
mod fitted;
mod model;
mod model_id;
pub mod models;
mod observations;
mod options;
mod registry;
pub mod spectral;
mod toggles;
pub mod trig;
pub mod varint;

pub use axis::{AxisKind, TimeAxis};
pub use error::TemporalError;
pub use fitted::FittedVoxel;
pub use model::{
    ModelConfig, ModelDescriptor, OutlierMode, PeriodicTerm, PreparedModel, TemporalModel,
    VoxelDescription,
};
pub use model_id::ModelId;
pub use observations::{ObservationsBuilder, Run, VoxelObservations};
pub use options::{ModelOptions, OptionDescriptor};
pub use registry::ModelRegistry;
pub use spectral::options::{Order, OrderCriterion, SpectralOptions};
pub use spectral::{Component, SpectralParameters, MAX_COMPONENTS};
pub use toggles::{ToggleBuilder, Toggles, MAX_TOGGLES};
