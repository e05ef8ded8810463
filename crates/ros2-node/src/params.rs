//! The node's parameters, served as every ROS 2 node serves them (`rcl_interfaces/srv`:
//! `~/list_parameters`, `~/get_parameters`, `~/get_parameter_types`,
//! `~/describe_parameters`; `~/set_parameters` and `~/set_parameters_atomically` answer
//! that they are read-only), so that `ros2 service call` and `ros2 param` clients read
//! them. The messages are `rcl_interfaces/msg` as ROS 2 Humble and later define them.

use serde::{Deserialize, Serialize};

/// `rcl_interfaces/msg/ParameterType` values.
pub mod parameter_type {
    /// Unset.
    pub const NOT_SET: u8 = 0;
    /// `bool`.
    pub const BOOL: u8 = 1;
    /// `int64`.
    pub const INTEGER: u8 = 2;
    /// `float64`.
    pub const DOUBLE: u8 = 3;
    /// `string`.
    pub const STRING: u8 = 4;
}

/// `rcl_interfaces/msg/ParameterValue`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ParameterValue {
    /// A [`parameter_type`].
    pub r#type: u8,
    /// The value of a `BOOL`.
    pub bool_value: bool,
    /// The value of an `INTEGER`.
    pub integer_value: i64,
    /// The value of a `DOUBLE`.
    pub double_value: f64,
    /// The value of a `STRING`.
    pub string_value: String,
    /// Array values (not used by the node's parameters).
    pub byte_array_value: Vec<u8>,
    /// See `byte_array_value`.
    pub bool_array_value: Vec<bool>,
    /// See `byte_array_value`.
    pub integer_array_value: Vec<i64>,
    /// See `byte_array_value`.
    pub double_array_value: Vec<f64>,
    /// See `byte_array_value`.
    pub string_array_value: Vec<String>,
}

impl ParameterValue {
    /// A `BOOL`.
    pub fn bool(value: bool) -> Self {
        Self {
            r#type: parameter_type::BOOL,
            bool_value: value,
            ..Self::default()
        }
    }

    /// An `INTEGER`.
    pub fn integer(value: i64) -> Self {
        Self {
            r#type: parameter_type::INTEGER,
            integer_value: value,
            ..Self::default()
        }
    }

    /// A `DOUBLE`.
    pub fn double(value: f64) -> Self {
        Self {
            r#type: parameter_type::DOUBLE,
            double_value: value,
            ..Self::default()
        }
    }

    /// A `STRING`.
    pub fn string(value: &str) -> Self {
        Self {
            r#type: parameter_type::STRING,
            string_value: value.to_string(),
            ..Self::default()
        }
    }

    /// A `-p name:=value` value as rcl reads it (a YAML scalar): `true`/`false` (any case),
    /// an integer, a number, else a string (quotes removed).
    pub fn from_yaml_scalar(text: &str) -> Self {
        let trimmed = text.trim();
        for quote in ['"', '\''] {
            if let Some(inner) = trimmed
                .strip_prefix(quote)
                .and_then(|t| t.strip_suffix(quote))
            {
                return Self::string(inner);
            }
        }
        match trimmed.to_ascii_lowercase().as_str() {
            "true" => return Self::bool(true),
            "false" => return Self::bool(false),
            _ => {}
        }
        if let Ok(integer) = trimmed.parse::<i64>() {
            return Self::integer(integer);
        }
        if let Ok(double) = trimmed.parse::<f64>() {
            if trimmed.contains(|c: char| c.is_ascii_digit()) {
                return Self::double(double);
            }
        }
        Self::string(trimmed)
    }

    /// The value as a command-line option takes it (`true`, `10`, `2.5`, `1h`).
    pub fn as_text(&self) -> String {
        match self.r#type {
            parameter_type::BOOL => self.bool_value.to_string(),
            parameter_type::INTEGER => self.integer_value.to_string(),
            parameter_type::DOUBLE => self.double_value.to_string(),
            _ => self.string_value.clone(),
        }
    }
}

/// `rcl_interfaces/msg/Parameter`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Parameter {
    /// Its name.
    pub name: String,
    /// Its value.
    pub value: ParameterValue,
}

/// `rcl_interfaces/srv/ListParameters` request.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ListParametersRequest {
    /// Names starting with one of these and a `.` (all when empty).
    pub prefixes: Vec<String>,
    /// How many `.`-separated levels below a prefix (0: all).
    pub depth: u64,
}

/// `rcl_interfaces/srv/ListParameters` response (its `ListParametersResult`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ListParametersResponse {
    /// The names.
    pub names: Vec<String>,
    /// The prefixes among them.
    pub prefixes: Vec<String>,
}

/// `rcl_interfaces/srv/GetParameters`, `GetParameterTypes` and `DescribeParameters`
/// request: names.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct NamesRequest {
    /// The parameters asked for.
    pub names: Vec<String>,
}

/// `rcl_interfaces/srv/GetParameters` response.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct GetParametersResponse {
    /// A value per name asked for (`NOT_SET` for an unknown one).
    pub values: Vec<ParameterValue>,
}

/// `rcl_interfaces/srv/GetParameterTypes` response.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct GetParameterTypesResponse {
    /// A [`parameter_type`] per name asked for.
    pub types: Vec<u8>,
}

/// `rcl_interfaces/msg/FloatingPointRange`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FloatingPointRange {
    /// From.
    pub from_value: f64,
    /// To.
    pub to_value: f64,
    /// Step.
    pub step: f64,
}

/// `rcl_interfaces/msg/IntegerRange`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct IntegerRange {
    /// From.
    pub from_value: i64,
    /// To.
    pub to_value: i64,
    /// Step.
    pub step: u64,
}

/// `rcl_interfaces/msg/ParameterDescriptor`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ParameterDescriptor {
    /// The name.
    pub name: String,
    /// A [`parameter_type`].
    pub r#type: u8,
    /// What it is.
    pub description: String,
    /// Constraints in words.
    pub additional_constraints: String,
    /// Always true here.
    pub read_only: bool,
    /// Whether its type may change.
    pub dynamic_typing: bool,
    /// Unused.
    pub floating_point_range: Vec<FloatingPointRange>,
    /// Unused.
    pub integer_range: Vec<IntegerRange>,
}

/// `rcl_interfaces/srv/DescribeParameters` response.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DescribeParametersResponse {
    /// A descriptor per name asked for.
    pub descriptors: Vec<ParameterDescriptor>,
}

/// `rcl_interfaces/srv/SetParameters` request (and `SetParametersAtomically`'s).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SetParametersRequest {
    /// The parameters to set.
    pub parameters: Vec<Parameter>,
}

/// `rcl_interfaces/msg/SetParametersResult`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SetParametersResult {
    /// Whether it was set.
    pub successful: bool,
    /// Why not.
    pub reason: String,
}

/// `rcl_interfaces/srv/SetParameters` response.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SetParametersResponse {
    /// A result per parameter.
    pub results: Vec<SetParametersResult>,
}

/// The node's parameters: read-only values with their descriptions.
#[derive(Clone, Debug, Default)]
pub struct Parameters {
    entries: Vec<(String, ParameterValue, String)>,
}

impl Parameters {
    /// Adds (or replaces) `name` with `value`, described by `description`.
    pub fn set(&mut self, name: &str, value: ParameterValue, description: &str) {
        match self.entries.iter_mut().find(|(n, _, _)| n == name) {
            Some(entry) => *entry = (name.to_string(), value, description.to_string()),
            None => {
                self.entries
                    .push((name.to_string(), value, description.to_string()));
                self.entries.sort_by(|a, b| a.0.cmp(&b.0));
            }
        }
    }

    /// The value of `name`.
    pub fn get(&self, name: &str) -> Option<&ParameterValue> {
        self.entries
            .iter()
            .find(|(n, _, _)| n == name)
            .map(|(_, v, _)| v)
    }

    pub(crate) fn list(&self, request: &ListParametersRequest) -> ListParametersResponse {
        // The node's names have no `.`: every one is at depth 1 below the empty prefix.
        let names = self
            .entries
            .iter()
            .map(|(n, _, _)| n.clone())
            .filter(|n| {
                request.prefixes.is_empty()
                    || request.prefixes.iter().any(|p| {
                        n.strip_prefix(p.as_str())
                            .is_some_and(|r| r.starts_with('.'))
                    })
            })
            .collect();
        ListParametersResponse {
            names,
            prefixes: Vec::new(),
        }
    }

    pub(crate) fn values(&self, request: &NamesRequest) -> GetParametersResponse {
        GetParametersResponse {
            values: request
                .names
                .iter()
                .map(|n| self.get(n).cloned().unwrap_or_default())
                .collect(),
        }
    }

    pub(crate) fn types(&self, request: &NamesRequest) -> GetParameterTypesResponse {
        GetParameterTypesResponse {
            types: request
                .names
                .iter()
                .map(|n| self.get(n).map_or(parameter_type::NOT_SET, |v| v.r#type))
                .collect(),
        }
    }

    pub(crate) fn describe(&self, request: &NamesRequest) -> DescribeParametersResponse {
        DescribeParametersResponse {
            descriptors: request
                .names
                .iter()
                .map(|name| {
                    let entry = self.entries.iter().find(|(n, _, _)| n == name);
                    ParameterDescriptor {
                        name: name.clone(),
                        r#type: entry.map_or(parameter_type::NOT_SET, |(_, v, _)| v.r#type),
                        description: entry.map(|(_, _, d)| d.clone()).unwrap_or_default(),
                        read_only: true,
                        ..ParameterDescriptor::default()
                    }
                })
                .collect(),
        }
    }

    pub(crate) fn refuse_set(&self, request: &SetParametersRequest) -> SetParametersResponse {
        SetParametersResponse {
            results: request
                .parameters
                .iter()
                .map(|p| SetParametersResult {
                    successful: false,
                    reason: format!(
                        "{} is read-only: froctomap takes its parameters at start (-p {}:=…)",
                        p.name, p.name
                    ),
                })
                .collect(),
        }
    }
}
