//! Arithmetic expressions in scene files: `"omega1^2"`, `"(1 - 1/omega)/sqrt(2)"`.
//!
//! Numbers, named parameters, `+ - * / ^` (right-associative power), parentheses,
//! the constants `pi` and `tau`, and the functions `sqrt exp ln log10 sin cos tan asin
//! acos atan abs` (one argument) and `min max atan2 pow` (two). A scene's `[parameters]`
//! may refer to each other; `--set name=value` replaces one before anything is evaluated.

use std::collections::BTreeMap;

/// Evaluate `text` with the parameter values `parameters`.
pub fn evaluate(text: &str, parameters: &BTreeMap<String, f64>) -> Result<f64, String> {
    evaluate_with_units(text, parameters, &[])
}

/// Evaluate `text` where a number may carry one of the unit suffixes `units` (name, factor):
/// `4fs`, `0.5 fs`, `10ps` are the number times the factor. A unit standing alone is its
/// factor, so inverse units read naturally: `1/ps` is `1 / 1000` in a scene timed in fs. A
/// suffix the table lacks is an error that says which scenes accept it.
pub fn evaluate_with_units(
    text: &str,
    parameters: &BTreeMap<String, f64>,
    units: &[(&str, f64)],
) -> Result<f64, String> {
    let mut parser = Parser {
        tokens: tokenize(text)?,
        position: 0,
        depth: 0,
        parameters,
        units,
    };
    let value = parser.expression()?;
    if parser.position != parser.tokens.len() {
        return Err(format!(
            "unexpected {} in expression \"{text}\"",
            parser.tokens[parser.position]
        ));
    }
    Ok(value)
}

/// Names an expression refers to that are not constants or functions.
pub fn referenced_names(text: &str) -> Result<Vec<String>, String> {
    let tokens = tokenize(text)?;
    Ok(tokens
        .iter()
        .enumerate()
        .filter_map(|(i, token)| match token {
            Token::Name(name)
                if !matches!(tokens.get(i + 1), Some(Token::Open)) && constant(name).is_none() =>
            {
                Some(name.clone())
            }
            _ => None,
        })
        .collect())
}

#[derive(Clone, Debug, PartialEq)]
enum Token {
    Number(f64),
    Name(String),
    Operator(char),
    Open,
    Close,
    Comma,
}

impl std::fmt::Display for Token {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Token::Number(x) => write!(f, "number {x}"),
            Token::Name(name) => write!(f, "name '{name}'"),
            Token::Operator(op) => write!(f, "'{op}'"),
            Token::Open => write!(f, "'('"),
            Token::Close => write!(f, "')'"),
            Token::Comma => write!(f, "','"),
        }
    }
}

fn tokenize(text: &str) -> Result<Vec<Token>, String> {
    let chars: Vec<char> = text.chars().collect();
    let mut tokens = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        if c.is_whitespace() {
            i += 1;
        } else if c.is_ascii_digit() || c == '.' {
            let start = i;
            while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
                i += 1;
            }
            // exponent: 1e-3, 2.5E+4
            if i < chars.len() && (chars[i] == 'e' || chars[i] == 'E') {
                let mut j = i + 1;
                if j < chars.len() && (chars[j] == '+' || chars[j] == '-') {
                    j += 1;
                }
                if j < chars.len() && chars[j].is_ascii_digit() {
                    i = j;
                    while i < chars.len() && chars[i].is_ascii_digit() {
                        i += 1;
                    }
                }
            }
            let literal: String = chars[start..i].iter().collect();
            let value = literal
                .parse::<f64>()
                .map_err(|_| format!("bad number \"{literal}\" in expression \"{text}\""))?;
            tokens.push(Token::Number(value));
        } else if c.is_alphabetic() || c == '_' {
            let start = i;
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            tokens.push(Token::Name(chars[start..i].iter().collect()));
        } else {
            tokens.push(match c {
                '+' | '-' | '*' | '/' | '^' => Token::Operator(c),
                '(' => Token::Open,
                ')' => Token::Close,
                ',' => Token::Comma,
                _ => {
                    return Err(format!(
                        "unexpected character '{c}' in expression \"{text}\""
                    ));
                }
            });
            i += 1;
        }
    }
    if tokens.is_empty() {
        return Err("empty expression".into());
    }
    Ok(tokens)
}

fn constant(name: &str) -> Option<f64> {
    match name {
        "pi" => Some(std::f64::consts::PI),
        "tau" => Some(std::f64::consts::TAU),
        _ => None,
    }
}

/// Deepest nesting an expression may have; far beyond any formula, far within the stack.
const MAX_DEPTH: usize = 200;

struct Parser<'a> {
    tokens: Vec<Token>,
    position: usize,
    depth: usize,
    parameters: &'a BTreeMap<String, f64>,
    units: &'a [(&'a str, f64)],
}

impl Parser<'_> {
    fn peek(&self) -> Option<&Token> {
        self.tokens.get(self.position)
    }

    fn next(&mut self) -> Option<Token> {
        let token = self.tokens.get(self.position).cloned();
        self.position += 1;
        token
    }

    fn expression(&mut self) -> Result<f64, String> {
        let mut value = self.product()?;
        while let Some(Token::Operator(op @ ('+' | '-'))) = self.peek().cloned() {
            self.position += 1;
            let rhs = self.product()?;
            value = if op == '+' { value + rhs } else { value - rhs };
        }
        Ok(value)
    }

    fn product(&mut self) -> Result<f64, String> {
        let mut value = self.unary()?;
        while let Some(Token::Operator(op @ ('*' | '/'))) = self.peek().cloned() {
            self.position += 1;
            let rhs = self.unary()?;
            value = if op == '*' { value * rhs } else { value / rhs };
        }
        Ok(value)
    }

    /// Every nesting (parentheses, calls, signs, powers) passes through here: the depth
    /// is bounded so that a deeply nested expression is an error, not a stack overflow.
    fn unary(&mut self) -> Result<f64, String> {
        if self.depth >= MAX_DEPTH {
            return Err(format!(
                "the expression nests deeper than {MAX_DEPTH} levels (parentheses, signs, powers)"
            ));
        }
        self.depth += 1;
        let value = self.unary_inner();
        self.depth -= 1;
        value
    }

    fn unary_inner(&mut self) -> Result<f64, String> {
        match self.peek() {
            Some(Token::Operator('-')) => {
                self.position += 1;
                Ok(-self.unary()?)
            }
            Some(Token::Operator('+')) => {
                self.position += 1;
                self.unary()
            }
            _ => self.power(),
        }
    }

    fn power(&mut self) -> Result<f64, String> {
        let base = self.atom()?;
        if let Some(Token::Operator('^')) = self.peek() {
            self.position += 1;
            let exponent = self.unary()?;
            return Ok(base.powf(exponent));
        }
        Ok(base)
    }

    fn atom(&mut self) -> Result<f64, String> {
        match self.next() {
            Some(Token::Number(x)) => match self.peek() {
                // A number followed by a name that is no parameter: a unit suffix.
                Some(Token::Name(name)) if !self.parameters.contains_key(name) => {
                    let name = name.clone();
                    match self.units.iter().find(|(unit, _)| *unit == name) {
                        Some(&(_, factor)) => {
                            self.position += 1;
                            Ok(x * factor)
                        }
                        None if crate::units::is_known_unit(&name) => Err(unit_not_accepted(&name)),
                        None => Err(format!("unknown unit '{name}' after {x}")),
                    }
                }
                _ => Ok(x),
            },
            Some(Token::Open) => {
                let value = self.expression()?;
                match self.next() {
                    Some(Token::Close) => Ok(value),
                    _ => Err("missing ')'".into()),
                }
            }
            Some(Token::Name(name)) => {
                if let Some(Token::Open) = self.peek() {
                    self.position += 1;
                    let mut arguments = vec![self.expression()?];
                    loop {
                        match self.next() {
                            Some(Token::Comma) => arguments.push(self.expression()?),
                            Some(Token::Close) => break,
                            _ => return Err(format!("missing ')' after arguments of {name}")),
                        }
                    }
                    call(&name, &arguments)
                } else if let Some(value) = self.parameters.get(&name) {
                    Ok(*value)
                } else if let Some(value) = constant(&name) {
                    Ok(value)
                } else if let Some(&(_, factor)) = self.units.iter().find(|(u, _)| *u == name) {
                    Ok(factor)
                } else if crate::units::is_known_unit(&name) {
                    Err(unit_not_accepted(&name))
                } else {
                    Err(format!("unknown parameter '{name}'"))
                }
            }
            Some(token) => Err(format!("unexpected {token}")),
            None => Err("expression ends too early".into()),
        }
    }
}

/// The error for a unit this value does not take: a real-scene unit in a dimensionless
/// scene, or a unit of another quantity (`K` for a time).
fn unit_not_accepted(name: &str) -> String {
    format!(
        "the unit '{name}' needs a scene with units = \"real\" and a value of its kind \
         (a time for fs, ps, ns; a temperature for K)"
    )
}

fn call(name: &str, arguments: &[f64]) -> Result<f64, String> {
    let one = |f: fn(f64) -> f64| match arguments {
        [x] => Ok(f(*x)),
        _ => Err(format!(
            "{name} takes one argument, got {}",
            arguments.len()
        )),
    };
    let two = |f: fn(f64, f64) -> f64| match arguments {
        [x, y] => Ok(f(*x, *y)),
        _ => Err(format!(
            "{name} takes two arguments, got {}",
            arguments.len()
        )),
    };
    match name {
        "sqrt" => one(f64::sqrt),
        "exp" => one(f64::exp),
        "ln" => one(f64::ln),
        "log10" => one(f64::log10),
        "sin" => one(f64::sin),
        "cos" => one(f64::cos),
        "tan" => one(f64::tan),
        "asin" => one(f64::asin),
        "acos" => one(f64::acos),
        "atan" => one(f64::atan),
        "abs" => one(f64::abs),
        "min" => two(f64::min),
        "max" => two(f64::max),
        "atan2" => two(f64::atan2),
        "pow" => two(f64::powf),
        _ => Err(format!("unknown function '{name}'")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eval(text: &str) -> f64 {
        let mut parameters = BTreeMap::new();
        parameters.insert("omega".to_string(), 50.0);
        evaluate(text, &parameters).unwrap()
    }

    #[test]
    fn precedence_and_functions() {
        assert_eq!(eval("1 + 2 * 3"), 7.0);
        assert_eq!(eval("2^3^2"), 512.0);
        assert_eq!(eval("-2^2"), -4.0);
        assert_eq!(eval("omega^2/2"), 1250.0);
        assert_eq!(
            eval("(1 - 1/omega)/sqrt(2)"),
            (1.0 - 1.0 / 50.0) / 2f64.sqrt()
        );
        assert_eq!(eval("1.5e-3 * 2"), 3e-3);
        assert_eq!(eval("max(1, 2) + pi"), 2.0 + std::f64::consts::PI);
    }

    #[test]
    fn errors_name_the_problem() {
        let empty = BTreeMap::new();
        assert!(
            evaluate("omega2 * 2", &empty)
                .unwrap_err()
                .contains("omega2")
        );
        assert!(evaluate("(1 + 2", &empty).unwrap_err().contains(')'));
        assert!(evaluate("1 + $", &empty).unwrap_err().contains('$'));
        assert!(evaluate("foo(1)", &empty).unwrap_err().contains("foo"));
    }

    #[test]
    fn time_units_multiply_the_number() {
        let empty = BTreeMap::new();
        let units = crate::units::Units::Real.time_units();
        assert_eq!(evaluate_with_units("4fs", &empty, units).unwrap(), 4.0);
        assert_eq!(evaluate_with_units("10ps", &empty, units).unwrap(), 1e4);
        assert_eq!(evaluate_with_units("0.5 fs", &empty, units).unwrap(), 0.5);
        assert_eq!(evaluate_with_units("2*1.5ps", &empty, units).unwrap(), 3e3);
        assert_eq!(evaluate_with_units("1e-3ns", &empty, units).unwrap(), 1e3);
        assert!(
            evaluate("4fs", &empty)
                .unwrap_err()
                .contains("units = \"real\"")
        );
        assert!(
            evaluate_with_units("4furlongs", &empty, units)
                .unwrap_err()
                .contains("unknown unit 'furlongs'")
        );
    }

    #[test]
    fn a_unit_alone_is_its_factor() {
        let empty = BTreeMap::new();
        let units = crate::units::Units::Real.time_units();
        assert_eq!(evaluate_with_units("1/ps", &empty, units).unwrap(), 1e-3);
        assert_eq!(evaluate_with_units("5/ns", &empty, units).unwrap(), 5e-6);
        let kelvin = crate::units::Units::Real.temperature_units();
        assert_eq!(evaluate_with_units("300K", &empty, kelvin).unwrap(), 300.0);
        // A time unit where a temperature is asked, and kelvin in a dimensionless scene.
        assert!(evaluate_with_units("300ps", &empty, kelvin).is_err());
        assert!(
            evaluate("300K", &empty)
                .unwrap_err()
                .contains("units = \"real\"")
        );
    }

    #[test]
    fn referenced_names_skip_functions_and_constants() {
        assert_eq!(
            referenced_names("sqrt(a) * pi + b").unwrap(),
            vec!["a".to_string(), "b".to_string()]
        );
    }
}
