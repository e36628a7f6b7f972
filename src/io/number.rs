//! Numbers as text: the shortest decimal that reads back to the same `f64`, in exponent
//! form when the plain form would be long (Rust's `{}` writes 1e300 as 301 digits).

use std::fmt;

/// `x` as the shortest round-trip text: plain (`0.25`, `1200`) between 1e-5 and 1e16,
/// exponent form (`1e300`, `2.5e-7`) outside; zero, infinities and NaN as `{}` writes them.
#[derive(Clone, Copy, Debug)]
pub struct Num(pub f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.0;
        let magnitude = x.abs();
        if x != 0.0 && x.is_finite() && !(1e-5..1e16).contains(&magnitude) {
            write!(f, "{x:e}")
        } else {
            write!(f, "{x}")
        }
    }
}

/// Rewrite every number in `text` that would print long (`h = 0.000…01`) in exponent form.
pub fn shorten_numbers(text: &str) -> String {
    text.split(' ')
        .map(|word| {
            let (body, tail) = match word.strip_suffix(',') {
                Some(body) => (body, ","),
                None => (word, ""),
            };
            match body.parse::<f64>() {
                Ok(x) if body.len() > 24 => format!("{}{tail}", Num(x)),
                _ => word.to_string(),
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plain_in_the_middle_exponent_outside() {
        assert_eq!(Num(0.25).to_string(), "0.25");
        assert_eq!(Num(1200.0).to_string(), "1200");
        assert_eq!(Num(0.0).to_string(), "0");
        assert_eq!(Num(1e300).to_string(), "1e300");
        assert_eq!(Num(-2.5e-7).to_string(), "-2.5e-7");
        assert_eq!(Num(f64::INFINITY).to_string(), "inf");
        for x in [1e300, 1e-300, 0.1 + 0.2, 123456.789, 5e-324] {
            assert_eq!(Num(x).to_string().parse::<f64>().unwrap(), x);
        }
        assert_eq!(
            shorten_numbers(&format!("h = {}, dt = 0.5", 1e-300)),
            "h = 1e-300, dt = 0.5"
        );
    }
}
