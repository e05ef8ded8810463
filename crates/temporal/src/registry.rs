//! Models as data: a registry resolving file-recorded ids and command-line names.

use crate::{ModelDescriptor, ModelId, PreparedModel, TemporalError, TimeAxis};

/// The models a program knows, looked up by id (reading files) or name (command lines).
///
/// ```
/// use froctomap_temporal::{ModelId, ModelRegistry};
/// let registry = ModelRegistry::with_default_models();
/// let fremen = registry.by_name(froctomap_temporal::models::DEFAULT_MODEL).unwrap();
/// assert_eq!(fremen.id, ModelId::FREMEN_PERIODS);
/// assert_eq!(registry.by_id(ModelId(0)).unwrap().name, "static");
/// assert!(registry.by_id(ModelId(999)).is_none());
/// assert_eq!(registry.names(), ["static", "fremen-regular", "fremen-periods", "markov"]);
/// assert!(fremen.options.iter().any(|o| o.key == "order" && o.default == "auto"));
/// ```
#[derive(Debug, Clone, Default)]
pub struct ModelRegistry {
    models: Vec<ModelDescriptor>,
}

impl ModelRegistry {
    /// An empty registry.
    pub fn new() -> Self {
        Self::default()
    }

    /// A registry of every built-in model ([`models::DEFAULT_MODELS`](crate::models::DEFAULT_MODELS)).
    pub fn with_default_models() -> Self {
        let mut registry = Self::new();
        for descriptor in crate::models::DEFAULT_MODELS {
            // Built-in ids and names are distinct (checked by a test).
            let _ = registry.register(*descriptor);
        }
        registry
    }

    /// Adds a model; its id and name must be new.
    pub fn register(&mut self, descriptor: ModelDescriptor) -> Result<(), TemporalError> {
        if self.by_id(descriptor.id).is_some() || self.by_name(descriptor.name).is_some() {
            return Err(TemporalError::DuplicateModel(format!(
                "{} (id {})",
                descriptor.name, descriptor.id
            )));
        }
        self.models.push(descriptor);
        Ok(())
    }

    /// The model with this id.
    pub fn by_id(&self, id: ModelId) -> Option<&ModelDescriptor> {
        self.models.iter().find(|d| d.id == id)
    }

    /// The names of every model, in registration order.
    pub fn names(&self) -> Vec<&'static str> {
        self.models.iter().map(|d| d.name).collect()
    }

    /// The model with this name.
    pub fn by_name(&self, name: &str) -> Option<&ModelDescriptor> {
        self.models.iter().find(|d| d.name == name)
    }

    /// Every model, in registration order.
    pub fn iter(&self) -> impl Iterator<Item = &ModelDescriptor> {
        self.models.iter()
    }

    /// What a reader does with a file header: the prepared model for a stored id and
    /// parameter block.
    pub fn prepare_from_parameters(
        &self,
        id: ModelId,
        axis: &TimeAxis,
        parameters: &[u8],
    ) -> Result<Box<dyn PreparedModel>, TemporalError> {
        self.by_id(id)
            .ok_or(TemporalError::UnknownModel(id))?
            .create()
            .prepare_from_parameters(axis, parameters)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TemporalModel;

    // Prepared models are shared across fitting threads.
    const _: () = {
        const fn shared<T: Send + Sync + ?Sized>() {}
        shared::<dyn PreparedModel>();
        shared::<dyn TemporalModel>();
        shared::<crate::models::PreparedFremenRegular>();
        shared::<crate::models::PreparedFremenPeriods>();
        shared::<ModelRegistry>();
    };

    #[test]
    fn parameters_with_trailing_bytes_are_rejected() {
        let axis = TimeAxis::regular(froctomap_core::Timestamp(0), 1, 10, vec![]).unwrap();
        let registry = ModelRegistry::with_default_models();
        for d in registry.iter() {
            let prepared = d.create().prepare(&axis, &Default::default()).unwrap();
            let mut params = prepared.encode_parameters();
            assert!(registry
                .prepare_from_parameters(d.id, &axis, &params)
                .is_ok());
            params.push(0);
            assert!(registry
                .prepare_from_parameters(d.id, &axis, &params)
                .is_err());
        }
        assert!(matches!(
            registry.prepare_from_parameters(ModelId(77), &axis, &[1, 0]),
            Err(TemporalError::UnknownModel(ModelId(77)))
        ));
    }

    #[test]
    fn defaults_are_distinct_and_consistent() {
        let registry = ModelRegistry::with_default_models();
        assert_eq!(registry.iter().count(), crate::models::DEFAULT_MODELS.len());
        for d in registry.iter() {
            let model = d.create();
            assert_eq!(model.id(), d.id);
            assert_eq!(model.name(), d.name);
        }
        // Every declared default is a value the model accepts, and gives its default config.
        let axis = TimeAxis::regular(froctomap_core::Timestamp(0), 1, 10, vec![]).unwrap();
        for d in registry.iter() {
            let mut explicit = crate::ModelOptions::new();
            for option in d.options {
                explicit.set(option.key, option.default);
            }
            let model = d.create();
            assert_eq!(model.check_options(&explicit), Ok(()), "{}", d.name);
            let config = crate::ModelConfig {
                options: explicit,
                ..Default::default()
            };
            let (Ok(a), Ok(b)) = (
                model.prepare(&axis, &config),
                model.prepare(&axis, &Default::default()),
            ) else {
                panic!("{}", d.name);
            };
            assert_eq!(a.encode_parameters(), b.encode_parameters());
        }
        let mut again = registry.clone();
        assert!(again.register(crate::models::DEFAULT_MODELS[0]).is_err());
    }
}
