//! `[parameters]` with `--set` overrides, and the numbers and vectors of a scene: plain
//! numbers or expressions in the parameters.

use std::collections::BTreeMap;

use super::Builder;
use crate::error::{Error, Result};
use crate::expr;
use crate::settings::Value;

/// Longest chain of parameters referring to one another (a → b → c …).
const MAX_CHAIN: usize = 1000;

impl Builder<'_> {
    /// `[parameters]` with the `--set` overrides applied, each evaluated once (they may
    /// refer to one another, without cycles).
    pub(super) fn resolve_parameters(
        &self,
        raw: &BTreeMap<String, Value>,
        overrides: &[String],
    ) -> Result<BTreeMap<String, f64>> {
        let mut raw = raw.clone();
        for setting in overrides {
            let Some((name, text)) = setting.split_once('=') else {
                return Err(Error::flag("--set", "--set expects name=value")
                    .expected("name=value")
                    .got(format!("\"{setting}\"")));
            };
            let name = name.trim();
            if !raw.contains_key(name) {
                let known: Vec<&str> = raw.keys().map(String::as_str).collect();
                return Err(Error::flag(
                    "--set",
                    format!(
                        "--set {name}: the scene {} has no parameter \"{name}\" (it has: {})",
                        self.path.display(),
                        if known.is_empty() {
                            "none".to_string()
                        } else {
                            known.join(", ")
                        }
                    ),
                ));
            }
            let text = text.trim();
            let value = match text.parse::<f64>() {
                Ok(number) => Value::Number(number),
                Err(_) => Value::Expression(text.to_string()),
            };
            raw.insert(name.to_string(), value);
        }
        let mut resolved = BTreeMap::new();
        for name in raw.keys() {
            self.resolve_parameter(name, &raw, &mut resolved, &mut Vec::new())?;
        }
        Ok(resolved)
    }

    fn resolve_parameter(
        &self,
        name: &str,
        raw: &BTreeMap<String, Value>,
        resolved: &mut BTreeMap<String, f64>,
        stack: &mut Vec<String>,
    ) -> Result<f64> {
        if let Some(&value) = resolved.get(name) {
            return Ok(value);
        }
        // Resolution recurses along a chain of references: bound it, as expressions are.
        if stack.len() >= MAX_CHAIN {
            return Err(self.error(format!(
                "parameter \"{}\" depends on a chain of more than {MAX_CHAIN} parameters",
                stack[0]
            )));
        }
        if stack.iter().any(|n| n == name) {
            stack.push(name.to_string());
            return Err(self.error(format!(
                "parameters refer to each other in a cycle: {}",
                stack.join(" -> ")
            )));
        }
        let value = match &raw[name] {
            Value::Number(x) => *x,
            Value::Expression(text) => {
                stack.push(name.to_string());
                let dependencies = expr::referenced_names(text)
                    .map_err(|e| self.error(format!("parameter \"{name}\": {e}")).key(name))?;
                for dependency in dependencies {
                    if raw.contains_key(&dependency) {
                        self.resolve_parameter(&dependency, raw, resolved, stack)?;
                    }
                }
                stack.pop();
                expr::evaluate(text, resolved)
                    .map_err(|e| self.error(format!("parameter \"{name}\": {e}")).key(name))?
            }
        };
        if !value.is_finite() {
            return Err(self
                .error(format!("parameter \"{name}\" is not finite ({value})"))
                .key(name));
        }
        resolved.insert(name.to_string(), value);
        Ok(value)
    }

    pub(super) fn evaluate(
        &self,
        v: &Value,
        parameters: &BTreeMap<String, f64>,
        what: &str,
        offset: usize,
    ) -> Result<f64> {
        let value = match v {
            Value::Number(x) => *x,
            Value::Expression(text) => expr::evaluate(text, parameters)
                .map_err(|e| self.error_at(offset, format!("{what}: {e}")))?,
        };
        if !value.is_finite() {
            return Err(self.error_at(offset, format!("{what} is not finite ({value})")));
        }
        Ok(value)
    }

    pub(super) fn vector(
        &self,
        values: &[Value],
        dim: usize,
        parameters: &BTreeMap<String, f64>,
        what: &str,
        offset: usize,
    ) -> Result<Vec<f64>> {
        if values.len() != dim {
            return Err(self
                .error_at(
                    offset,
                    format!(
                        "{what} has {} components, but the scene has dim = {dim}",
                        values.len()
                    ),
                )
                .expected(format!("{dim} components")));
        }
        values
            .iter()
            .map(|v| self.evaluate(v, parameters, what, offset))
            .collect()
    }
}
