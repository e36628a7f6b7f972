//! Symmetric quadratures on `[0, 1]` for the pseudo-energy schemes (MEMM18 (8)–(11)).
//!
//! A rule is a list of nodes `τ_i ∈ [0, 1]` and weights `w_i` with `Σ w_i = 1`, so that
//! `∫_{t^n}^{t^n + h} f ≈ h Σ w_i f(t^n + τ_i h)`. MEMM18 writes the node as
//! `λ_i t^n + (1 − λ_i) t^{n+1}`, i.e. `τ_i = 1 − λ_i`; with the symmetry (11) both
//! orderings are the same rule.
//!
//! Nodes and weights are computed, not typed in: Gauss–Legendre nodes are the roots of the
//! Legendre polynomial `P_n` (Newton from Chebyshev guesses), with weights
//! `2 / ((1 − x²) P_n′(x)²)`; Gauss–Lobatto nodes are `±1` and the roots of `P_{n−1}′`,
//! with weights `2 / (n (n − 1) P_{n−1}(x)²)` (both on `[−1, 1]`, then mapped). Only the
//! nodes in `[−1, 0]` are computed and the others mirrored, so the rule is symmetric to the
//! last bit (needed for time reversibility, MEMM18 Prop. 4), and the Lobatto end nodes are
//! exactly `0` and `1` (so the end-of-step gradient can be reused as the next step's
//! first).
//!
//! Exactness (MEMM18 Remark 2): midpoint integrates polynomials of degree 1, the
//! `n`-point Gauss–Lobatto rule degree `2n − 3`, the `n`-point Gauss–Legendre rule degree
//! `2n − 1`.

use crate::error::{Error, Result};

/// The quadratures `--quadrature` accepts, with a line of help each.
pub const QUADRATURES: &[(&str, &str)] = &[
    ("midpoint", "1 node, exact for degree 1"),
    (
        "gl3",
        "Gauss–Lobatto, 3 nodes (Simpson), exact for degree 3",
    ),
    ("gl5", "Gauss–Lobatto, 5 nodes, exact for degree 7"),
    ("gauss3", "Gauss–Legendre, 3 nodes, exact for degree 5"),
    ("gauss5", "Gauss–Legendre, 5 nodes, exact for degree 9"),
];

#[derive(Clone, Debug, PartialEq)]
pub struct Quadrature {
    name: String,
    /// Nodes in `[0, 1]`, increasing.
    nodes: Vec<f64>,
    /// Weights summing to 1.
    weights: Vec<f64>,
    /// Highest polynomial degree integrated exactly.
    degree: usize,
}

impl Quadrature {
    /// A rule by its command-line name (see [`QUADRATURES`]).
    pub fn by_name(name: &str) -> Result<Self> {
        match name {
            "midpoint" => Ok(Self::midpoint()),
            "gl3" => Self::gauss_lobatto(3),
            "gl5" => Self::gauss_lobatto(5),
            "gauss3" => Self::gauss_legendre(3),
            "gauss5" => Self::gauss_legendre(5),
            other => {
                let known: Vec<&str> = QUADRATURES.iter().map(|(n, _)| *n).collect();
                Err(Error::setting(
                    "quadrature",
                    format!(
                        "unknown quadrature \"{other}\"; known quadratures: {}",
                        known.join(", ")
                    ),
                )
                .expected(known.join(", "))
                .got_named(other))
            }
        }
    }

    /// The midpoint rule: one node at `1/2`.
    pub fn midpoint() -> Self {
        Quadrature {
            name: "midpoint".into(),
            nodes: vec![0.5],
            weights: vec![1.0],
            degree: 1,
        }
    }

    /// The `n`-point Gauss–Legendre rule (`n ≥ 1`), exact for degree `2n − 1`.
    pub fn gauss_legendre(n: usize) -> Result<Self> {
        if n == 0 {
            return Err(Error::input("a Gauss–Legendre rule needs at least 1 node"));
        }
        // Roots x_k of P_n in [−1, 0], by Newton from the Chebyshev guess cos(π(k + 3/4)/(n + 1/2)).
        let half = n.div_ceil(2);
        let mut left = Vec::with_capacity(half);
        for k in 0..half {
            let mut x = -(std::f64::consts::PI * (k as f64 + 0.75) / (n as f64 + 0.5)).cos();
            if n % 2 == 1 && k + 1 == half {
                x = 0.0;
            } else {
                for _ in 0..100 {
                    let (p, dp) = legendre_with_derivative(n, x);
                    let dx = p / dp;
                    x -= dx;
                    if dx.abs() < 1e-16 {
                        break;
                    }
                }
            }
            let (_, dp) = legendre_with_derivative(n, x);
            left.push((x, 2.0 / ((1.0 - x * x) * dp * dp)));
        }
        Ok(Self::mirrored(format!("gauss{n}"), n, &left, 2 * n - 1))
    }

    /// The `n`-point Gauss–Lobatto rule (`n ≥ 2`), exact for degree `2n − 3`; its end
    /// nodes are exactly 0 and 1.
    pub fn gauss_lobatto(n: usize) -> Result<Self> {
        if n < 2 {
            return Err(Error::input("a Gauss–Lobatto rule needs at least 2 nodes"));
        }
        let m = n - 1;
        let end_weight = 2.0 / (n * m) as f64;
        let half = n.div_ceil(2);
        let mut left = Vec::with_capacity(half);
        left.push((-1.0, end_weight));
        // Interior nodes: roots of P_m′, i.e. of g(x) = P_{m−1}(x) − x P_m(x)
        // (since (1 − x²) P_m′ = m (P_{m−1} − x P_m)), by Newton from Chebyshev–Lobatto guesses.
        for k in 1..half {
            let mut x = -(std::f64::consts::PI * k as f64 / m as f64).cos();
            if n % 2 == 1 && k + 1 == half {
                x = 0.0;
            } else {
                for _ in 0..100 {
                    let (pm1, dpm1) = legendre_with_derivative(m - 1, x);
                    let (pm, dpm) = legendre_with_derivative(m, x);
                    let g = pm1 - x * pm;
                    let dg = dpm1 - pm - x * dpm;
                    let dx = g / dg;
                    x -= dx;
                    if dx.abs() < 1e-16 {
                        break;
                    }
                }
            }
            let (pm, _) = legendre_with_derivative(m, x);
            left.push((x, end_weight / (pm * pm)));
        }
        Ok(Self::mirrored(format!("lobatto{n}"), n, &left, 2 * n - 3))
    }

    /// Build a symmetric rule on `[0, 1]` from its nodes and weights on `[−1, 0]`
    /// (`left`, increasing; a node at 0 is the middle one when `n` is odd).
    fn mirrored(name: String, n: usize, left: &[(f64, f64)], degree: usize) -> Self {
        let mut nodes = vec![0.0; n];
        let mut weights = vec![0.0; n];
        for (k, &(x, w)) in left.iter().enumerate() {
            // τ = (1 + x)/2 on the left; the mirror node is 1 − τ, computed as (1 − x)/2 so
            // that τ + τ_mirror = 1 exactly when both are representable.
            nodes[k] = 0.5 * (1.0 + x);
            weights[k] = 0.5 * w;
            nodes[n - 1 - k] = 0.5 * (1.0 - x);
            weights[n - 1 - k] = 0.5 * w;
        }
        let name = match name.as_str() {
            "lobatto3" => "gl3".to_string(),
            "lobatto5" => "gl5".to_string(),
            _ => name,
        };
        Quadrature {
            name,
            nodes,
            weights,
            degree,
        }
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Nodes `τ_i ∈ [0, 1]`, increasing.
    pub fn nodes(&self) -> &[f64] {
        &self.nodes
    }

    /// Weights `w_i`, summing to 1.
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Highest polynomial degree the rule integrates exactly.
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// Whether the first node is 0 and the last 1 (Gauss–Lobatto): the gradient at the end
    /// of a step is then the next step's first, and a step costs `n − 1` evaluations.
    pub fn has_end_nodes(&self) -> bool {
        self.nodes.first() == Some(&0.0) && self.nodes.last() == Some(&1.0)
    }

    /// Gradient evaluations per step once the end nodes are reused.
    pub fn evaluations_per_step(&self) -> usize {
        if self.has_end_nodes() {
            self.len() - 1
        } else {
            self.len()
        }
    }

    /// `∫₀¹ f ≈ Σ w_i f(τ_i)` (for tests and small studies).
    pub fn integrate(&self, f: impl Fn(f64) -> f64) -> f64 {
        self.nodes
            .iter()
            .zip(&self.weights)
            .map(|(&t, &w)| w * f(t))
            .sum()
    }
}

/// `(P_n(x), P_n′(x))` by the three-term recurrence
/// `(k + 1) P_{k+1} = (2k + 1) x P_k − k P_{k−1}` and `P_n′ = n (x P_n − P_{n−1}) / (x² − 1)`
/// (valid inside `(−1, 1)`, where every node search happens).
fn legendre_with_derivative(n: usize, x: f64) -> (f64, f64) {
    if n == 0 {
        return (1.0, 0.0);
    }
    let (mut previous, mut current) = (1.0, x);
    for k in 1..n {
        let next = ((2 * k + 1) as f64 * x * current - k as f64 * previous) / (k + 1) as f64;
        previous = current;
        current = next;
    }
    let derivative = n as f64 * (x * current - previous) / (x * x - 1.0);
    (current, derivative)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `∫₀¹ t^k dt = 1/(k + 1)`; the rule's error on it, relative.
    fn monomial_error(rule: &Quadrature, k: i32) -> f64 {
        let exact = 1.0 / (k + 1) as f64;
        (rule.integrate(|t| t.powi(k)) - exact).abs() / exact
    }

    #[test]
    fn every_rule_is_exact_to_its_degree_and_not_beyond() {
        for (name, _) in QUADRATURES {
            let rule = Quadrature::by_name(name).unwrap();
            let d = rule.degree() as i32;
            // Exact up to round-off: a few ulps per node of sums of O(1) terms.
            for k in 0..=d {
                let error = monomial_error(&rule, k);
                assert!(
                    error < 16.0 * f64::EPSILON,
                    "{name}: degree {k} error {error:e}"
                );
            }
            // The next degree is not integrated exactly: the error is the rule's error
            // constant, far above round-off (≥ 1e-5 for every rule here).
            let error = monomial_error(&rule, d + 1);
            assert!(error > 1e-6, "{name}: degree {} error {error:e}", d + 1);
        }
    }

    #[test]
    fn rules_are_symmetric_and_lobatto_ends_are_exact() {
        for (name, _) in QUADRATURES {
            let rule = Quadrature::by_name(name).unwrap();
            let n = rule.len();
            for i in 0..n {
                assert_eq!(rule.nodes()[i] + rule.nodes()[n - 1 - i], 1.0, "{name}");
                assert_eq!(rule.weights()[i], rule.weights()[n - 1 - i], "{name}");
            }
        }
        let gl3 = Quadrature::by_name("gl3").unwrap();
        assert!(gl3.has_end_nodes());
        assert_eq!(gl3.evaluations_per_step(), 2);
        assert!(!Quadrature::by_name("gauss3").unwrap().has_end_nodes());
    }

    #[test]
    fn closed_forms_of_small_rules() {
        // Simpson: 1/6, 2/3, 1/6; Lobatto 5 on [−1, 1]: nodes 0, ±√(3/7), weights
        // 32/45, 49/90, 1/10; Gauss 3: nodes 0, ±√(3/5), weights 8/9, 5/9.
        let close = |a: f64, b: f64| (a - b).abs() < 4.0 * f64::EPSILON;
        let gl3 = Quadrature::by_name("gl3").unwrap();
        assert!(close(gl3.weights()[0], 1.0 / 6.0) && close(gl3.weights()[1], 2.0 / 3.0));
        let gl5 = Quadrature::by_name("gl5").unwrap();
        assert!(close(gl5.nodes()[1], 0.5 * (1.0 - (3.0f64 / 7.0).sqrt())));
        assert!(close(gl5.weights()[1], 0.5 * 49.0 / 90.0));
        assert!(close(gl5.weights()[2], 0.5 * 32.0 / 45.0));
        let gauss3 = Quadrature::by_name("gauss3").unwrap();
        assert!(close(gauss3.nodes()[0], 0.5 * (1.0 - (0.6f64).sqrt())));
        assert!(close(gauss3.weights()[0], 0.5 * 5.0 / 9.0));
    }

    #[test]
    fn unknown_names_are_rejected() {
        let error = Quadrature::by_name("simpson").unwrap_err().to_string();
        assert!(error.contains("gl3") && error.contains("simpson"));
    }
}
