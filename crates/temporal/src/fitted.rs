//! A fitted voxel: the model's parameter bytes (opaque here) plus its outlier set.

use crate::toggles::Toggles;

/// Parameter bytes kept inline before spilling to the heap: a FreMEn voxel of order 5 takes
/// at most 38 bytes, so almost every voxel fits without an allocation.
const INLINE_BYTES: usize = 46;

/// A short byte string stored inline when it fits.
#[derive(Clone)]
enum ParameterBytes {
    Inline { len: u8, bytes: [u8; INLINE_BYTES] },
    Heap(Box<[u8]>),
}

impl ParameterBytes {
    fn new(bytes: &[u8]) -> Self {
        let mut inline = [0u8; INLINE_BYTES];
        match inline.get_mut(..bytes.len()) {
            Some(prefix) => {
                prefix.copy_from_slice(bytes);
                ParameterBytes::Inline {
                    len: bytes.len() as u8,
                    bytes: inline,
                }
            }
            None => ParameterBytes::Heap(bytes.into()),
        }
    }

    fn as_slice(&self) -> &[u8] {
        match self {
            ParameterBytes::Inline { len, bytes } => bytes.get(..usize::from(*len)).unwrap_or(&[]),
            ParameterBytes::Heap(bytes) => bytes,
        }
    }
}

impl Default for ParameterBytes {
    fn default() -> Self {
        Self::new(&[])
    }
}

/// The fitted model of one voxel: the model's encoded parameters, its outlier toggles, and
/// (right after fitting) how many observed samples the model alone gets wrong.
///
/// The parameter bytes belong to the model that fitted them: a container stores them
/// verbatim, finds where they end with
/// [`PreparedModel::parameters_len`](crate::PreparedModel::parameters_len) and evaluates them
/// through the same [`PreparedModel`](crate::PreparedModel).
///
/// Equality compares parameters and toggles, not [`model_errors`](Self::model_errors).
#[derive(Clone, Default)]
pub struct FittedVoxel {
    parameters: ParameterBytes,
    toggles: Toggles,
    model_errors: Option<u64>,
}

impl std::fmt::Debug for FittedVoxel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FittedVoxel")
            .field("parameters", &self.parameters())
            .field("toggles", &self.toggles)
            .field("model_errors", &self.model_errors)
            .finish()
    }
}

impl PartialEq for FittedVoxel {
    fn eq(&self, other: &Self) -> bool {
        self.parameters() == other.parameters() && self.toggles == other.toggles
    }
}

impl FittedVoxel {
    /// A voxel from a model's parameter bytes and an outlier set.
    ///
    /// ```
    /// use froctomap_temporal::{FittedVoxel, Toggles};
    /// let voxel = FittedVoxel::new(&[0xff, 0x7f, 0], Toggles::new(vec![3])?);
    /// assert_eq!(voxel.parameters(), &[0xff, 0x7f, 0]);
    /// assert_eq!(voxel.model_errors(), None);
    /// # Ok::<(), froctomap_temporal::TemporalError>(())
    /// ```
    pub fn new(parameters: &[u8], toggles: Toggles) -> Self {
        Self {
            parameters: ParameterBytes::new(parameters),
            toggles,
            model_errors: None,
        }
    }

    /// The same model with another outlier set (for containers that store toggles apart).
    pub fn with_toggles(mut self, toggles: Toggles) -> Self {
        self.toggles = toggles;
        self
    }

    /// The same voxel, recording how many observed samples the model alone gets wrong
    /// (models set this when fitting).
    pub fn with_model_errors(mut self, errors: u64) -> Self {
        self.model_errors = Some(errors);
        self
    }

    /// The model's encoded parameters (layout defined by the model; see the crate docs).
    pub fn parameters(&self) -> &[u8] {
        self.parameters.as_slice()
    }

    /// The outlier set (empty in lossy mode).
    pub fn toggles(&self) -> &Toggles {
        &self.toggles
    }

    /// Observed samples where the thresholded model (without outliers) is wrong, known right
    /// after fitting (`None` for a decoded voxel: use
    /// [`PreparedModel::reconstruction_error`](crate::PreparedModel::reconstruction_error)).
    pub fn model_errors(&self) -> Option<u64> {
        self.model_errors
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_and_long_parameters_round_trip() {
        for len in [0, 1, INLINE_BYTES - 1, INLINE_BYTES, INLINE_BYTES + 1, 1000] {
            let bytes: Vec<u8> = (0..len).map(|i| i as u8).collect();
            let voxel = FittedVoxel::new(&bytes, Toggles::empty());
            assert_eq!(voxel.parameters(), &bytes[..]);
            assert_eq!(voxel.clone(), voxel);
        }
        assert_ne!(
            FittedVoxel::new(&[1], Toggles::empty()),
            FittedVoxel::new(&[1, 0], Toggles::empty())
        );
    }
}
