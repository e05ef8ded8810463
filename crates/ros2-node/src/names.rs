//! ROS command-line arguments (`--ros-args -r from:=to -r __ns:=/robot1 -r __node:=name
//! -p name:=value`) and ROS name resolution: a relative name (`octomap_binary`) is put in
//! the node's namespace, a private one (`~/predicted`) under the node's namespace and name,
//! an absolute one (`/clock`) stays; then the remapping rules apply to the resolved name,
//! as rcl applies them.

use crate::error::NodeError;
use crate::params::ParameterValue;

/// The node's default name.
pub const NODE_NAME: &str = "froctomap";

/// The DDS topic name of a ROS topic (`/a/b` → `rt/a/b`), as every ROS 2 RMW maps it.
pub fn dds_topic_name(ros_topic: &str) -> Result<String, NodeError> {
    let name = ros_topic.strip_prefix('/').unwrap_or(ros_topic);
    let valid = !name.is_empty()
        && !name.starts_with('/')
        && !name.contains("//")
        && !name.ends_with('/')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '/')
        && !name.starts_with(|c: char| c.is_ascii_digit());
    if valid {
        Ok(format!("rt/{name}"))
    } else {
        Err(NodeError::TopicName(ros_topic.to_string()))
    }
}

/// What `--ros-args` says: the node's name and namespace, remapping rules and parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct RosArgs {
    /// The node's name (`__node:=`; default [`NODE_NAME`]).
    pub node_name: String,
    /// The node's namespace (`__ns:=`; default `/`).
    pub namespace: String,
    /// Remapping rules `from:=to`, in their order (the first match wins, as in rcl).
    pub remaps: Vec<(String, String)>,
    /// Parameters `-p name:=value`, in their order (a later one overrides).
    pub parameters: Vec<(String, ParameterValue)>,
}

impl Default for RosArgs {
    fn default() -> Self {
        Self {
            node_name: NODE_NAME.to_string(),
            namespace: "/".to_string(),
            remaps: Vec::new(),
            parameters: Vec::new(),
        }
    }
}

impl RosArgs {
    /// Parses the arguments after `--ros-args` (up to a `--` or their end): `-r`/`--remap
    /// from:=to` (`__ns`, `__node` and `__name` set the namespace and name), `-p`/`--param
    /// name:=value` (the value read as YAML scalars are: `true`/`false`, an integer, a
    /// number, else a string; quotes keep a string). A remap rule may name the node it is for
    /// (`node:from:=to`, skipped for another node) and mark its kind (`rostopic://`,
    /// `rosservice://`); a rule whose `from` is no valid name matches nothing, as in rcl.
    /// `--params-file`, `--log-level`, `-e`/`--enclave` (each with its value) and the
    /// `--disable-…-logs`/`--enable-…-logs` flags are accepted and ignored with a warning.
    /// Anything else is an error naming it.
    ///
    /// ```
    /// use froctomap_ros2_node::RosArgs;
    /// let args: Vec<String> = ["-r", "__ns:=/robot1", "-r", "octomap_binary:=map_in", "-p", "use_sim_time:=true"]
    ///     .iter().map(|s| s.to_string()).collect();
    /// let ros = RosArgs::parse(&args)?;
    /// assert_eq!(ros.resolve("octomap_binary")?, "/robot1/map_in");
    /// assert_eq!(ros.resolve("~/predicted")?, "/robot1/froctomap/predicted");
    /// assert_eq!(ros.resolve("/clock")?, "/clock");
    /// # Ok::<(), froctomap_ros2_node::NodeError>(())
    /// ```
    pub fn parse(args: &[String]) -> Result<Self, NodeError> {
        let mut ros = Self::default();
        let mut args = args.iter();
        let bad = |text: String| NodeError::RosArgs(text);
        // Topic rules with the node they are for (`node:from:=to`), kept until the node's
        // name is known: a later `__node` renames it.
        let mut remaps: Vec<(Option<String>, String, String)> = Vec::new();
        while let Some(flag) = args.next() {
            match flag.as_str() {
                "--" => break,
                "--ros-args" => {}
                "-r" | "--remap" | "-p" | "--param" => {
                    let rule = args
                        .next()
                        .ok_or_else(|| bad(format!("{flag} needs a `name:=value` after it")))?;
                    let (name, value) = rule
                        .split_once(":=")
                        .ok_or_else(|| bad(format!("{flag} {rule}: not a `name:=value` rule")))?;
                    if name.is_empty() {
                        return Err(bad(format!("{flag} {rule}: no name before `:=`")));
                    }
                    if flag.starts_with("-p") || flag == "--param" {
                        ros.parameters
                            .push((name.to_string(), ParameterValue::from_yaml_scalar(value)));
                        continue;
                    }
                    let (node, name) = split_node_prefix(name);
                    match name {
                        "__ns" | "__node" | "__name" if node.is_some_and(|n| n != NODE_NAME) => {
                            // For another node (rcl matches the name the node is created with).
                        }
                        "__ns" => {
                            if !value.starts_with('/') {
                                return Err(bad(format!(
                                    "-r {rule}: a namespace is absolute (starts with /)"
                                )));
                            }
                            let trimmed = value.trim_end_matches('/');
                            dds_topic_name(&format!("{trimmed}/x"))
                                .map_err(|_| bad(format!("-r {rule}: not a namespace")))?;
                            ros.namespace = if trimmed.is_empty() {
                                "/".to_string()
                            } else {
                                trimmed.to_string()
                            };
                        }
                        "__node" | "__name" => {
                            let valid = !value.is_empty()
                                && !value.starts_with(|c: char| c.is_ascii_digit())
                                && value.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
                            if !valid {
                                return Err(bad(format!("-r {rule}: not a node name")));
                            }
                            ros.node_name = value.to_string();
                        }
                        _ => {
                            let from = name
                                .strip_prefix("rostopic://")
                                .or_else(|| name.strip_prefix("rosservice://"))
                                .unwrap_or(name);
                            remaps.push((node.map(str::to_string), from.to_string(), value.into()));
                        }
                    }
                }
                "--params-file" | "--log-level" | "-e" | "--enclave" => {
                    let value = args
                        .next()
                        .ok_or_else(|| bad(format!("{flag} needs a value after it")))?;
                    log::warn!("--ros-args {flag} {value}: not used by froctomap, ignored");
                }
                "--disable-rosout-logs"
                | "--disable-stdout-logs"
                | "--disable-external-lib-logs"
                | "--enable-rosout-logs"
                | "--enable-stdout-logs"
                | "--enable-external-lib-logs" => {
                    log::warn!("--ros-args {flag}: not used by froctomap, ignored");
                }
                other => {
                    return Err(bad(format!(
                    "`{other}` is not a ROS argument froctomap takes (-r from:=to, -p name:=value)"
                )))
                }
            }
        }
        ros.remaps = remaps
            .into_iter()
            .filter(|(node, _, _)| node.as_ref().is_none_or(|n| *n == ros.node_name))
            .map(|(_, from, to)| (from, to))
            .collect();
        Ok(ros)
    }

    /// `name` expanded in the node's namespace, without remapping.
    fn expand(&self, name: &str) -> Result<String, NodeError> {
        let ns = self.namespace.trim_end_matches('/');
        let expanded = if name.starts_with('/') {
            name.to_string()
        } else if name == "~" {
            format!("{ns}/{}", self.node_name)
        } else if let Some(private) = name.strip_prefix("~/") {
            format!("{ns}/{}/{private}", self.node_name)
        } else {
            format!("{ns}/{name}")
        };
        dds_topic_name(&expanded)?;
        Ok(expanded)
    }

    /// The fully qualified name a topic or service `name` resolves to: expanded, then
    /// remapped by the first rule whose (expanded) `from` is it.
    pub fn resolve(&self, name: &str) -> Result<String, NodeError> {
        let expanded = self.expand(name)?;
        for (from, to) in &self.remaps {
            // A rule whose `from` is no valid name matches nothing (rcl skips it too).
            if self.expand(from).is_ok_and(|from| from == expanded) {
                return self.expand(to);
            }
        }
        Ok(expanded)
    }

    /// The node's fully qualified name (`/froctomap`, `/robot1/mapper`).
    pub fn fully_qualified_node_name(&self) -> String {
        format!(
            "{}/{}",
            self.namespace.trim_end_matches('/'),
            self.node_name
        )
    }

    /// The last value `-p name:=…` gave.
    pub fn parameter(&self, name: &str) -> Option<&ParameterValue> {
        self.parameters
            .iter()
            .rev()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v)
    }
}

/// `node:name` as the node a rule is for and the name (`rostopic://x` has no node).
fn split_node_prefix(name: &str) -> (Option<&str>, &str) {
    match name.split_once(':') {
        Some((node, rest)) if !node.is_empty() && !rest.starts_with("//") => (Some(node), rest),
        _ => (None, name),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> Result<RosArgs, NodeError> {
        RosArgs::parse(&args.iter().map(|s| s.to_string()).collect::<Vec<_>>())
    }

    #[test]
    fn names_resolve_as_rcl_resolves_them() {
        let plain = parse(&[]).expect("no arguments");
        assert_eq!(
            plain.resolve("octomap_binary").ok().as_deref(),
            Some("/octomap_binary")
        );
        assert_eq!(
            plain.resolve("~/predicted").ok().as_deref(),
            Some("/froctomap/predicted")
        );
        assert_eq!(plain.fully_qualified_node_name(), "/froctomap");
        let ros = parse(&[
            "-r",
            "__ns:=/robot1/",
            "-r",
            "__node:=mapper",
            "-r",
            "~/predicted:=/viz/predicted",
            "--remap",
            "octomap_binary:=octomap_full",
            "-p",
            "horizon:=1h",
            "-p",
            "x:=3",
            "-p",
            "y:=2.5",
            "-p",
            "z:=\"7\"",
            "-p",
            "use_sim_time:=True",
            "--",
        ])
        .expect("parses");
        assert_eq!(ros.fully_qualified_node_name(), "/robot1/mapper");
        assert_eq!(
            ros.resolve("octomap_binary").ok().as_deref(),
            Some("/robot1/octomap_full")
        );
        assert_eq!(
            ros.resolve("~/predicted").ok().as_deref(),
            Some("/viz/predicted")
        );
        assert_eq!(
            ros.resolve("~/dynamic").ok().as_deref(),
            Some("/robot1/mapper/dynamic")
        );
        assert_eq!(ros.resolve("/clock").ok().as_deref(), Some("/clock"));
        assert_eq!(
            ros.parameter("horizon"),
            Some(&ParameterValue::string("1h"))
        );
        assert_eq!(ros.parameter("x"), Some(&ParameterValue::integer(3)));
        assert_eq!(ros.parameter("y"), Some(&ParameterValue::double(2.5)));
        assert_eq!(ros.parameter("z"), Some(&ParameterValue::string("7")));
        assert_eq!(
            ros.parameter("use_sim_time"),
            Some(&ParameterValue::bool(true))
        );
        for bad in [
            &["-r"][..],
            &["-r", "a=b"],
            &["-r", "__ns:=robot1"],
            &["-r", "__node:=1x"],
            &["--log-level"],
            &["--frobnicate"],
            &["-p", ":=3"],
        ] {
            assert!(parse(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn the_root_namespace_is_accepted() {
        let ros = parse(&["-r", "__ns:=/"]).expect("root namespace");
        assert_eq!(ros.namespace, "/");
        assert_eq!(ros.fully_qualified_node_name(), "/froctomap");
        assert_eq!(ros.resolve("a").ok().as_deref(), Some("/a"));
    }

    #[test]
    fn rules_rcl_accepts_do_not_abort() {
        let ros = parse(&[
            "--ros-args",
            "--log-level",
            "debug",
            "--params-file",
            "/tmp/params.yaml",
            "-e",
            "/enclave",
            "--enclave",
            "/enclave",
            "--disable-rosout-logs",
            "--disable-stdout-logs",
            "--disable-external-lib-logs",
            // For another node: skipped, whatever it says.
            "-r",
            "other:octomap_binary:=elsewhere",
            "-r",
            "other:__ns:=/elsewhere",
            "-r",
            "other:__node:=elsewhere",
            // For this node, renamed later: applies.
            "-r",
            "froctomap:__ns:=/robot1",
            "-r",
            "mapper:octomap_binary:=map_in",
            "-r",
            "rostopic://clock:=/sim/clock",
            "-r",
            "mapper:rosservice://~/get:=/get_map",
            // A `from` that is no valid name: matches nothing.
            "-r",
            "bad name!:=x",
            "-r",
            "__node:=mapper",
        ])
        .expect("parses");
        assert_eq!(ros.fully_qualified_node_name(), "/robot1/mapper");
        assert_eq!(
            ros.resolve("octomap_binary").ok().as_deref(),
            Some("/robot1/map_in")
        );
        assert_eq!(ros.resolve("clock").ok().as_deref(), Some("/sim/clock"));
        assert_eq!(ros.resolve("~/get").ok().as_deref(), Some("/get_map"));
        assert_eq!(ros.resolve("other").ok().as_deref(), Some("/robot1/other"));
        // Only for another node.
        let other = parse(&["-r", "talker:octomap_binary:=x"]).expect("parses");
        assert_eq!(
            other.resolve("octomap_binary").ok().as_deref(),
            Some("/octomap_binary")
        );
    }
}
