//! The C² quintic switch `S(r)` from 1 at `r_in` to 0 at `r_out`: the smoothstep
//! `S = 1 − 10t³ + 15t⁴ − 6t⁵ = u³(10 − 15u + 6u²)` (`u = 1 − t`), `t = (r − r_in)/(r_out −
//! r_in)` on `[r_in, r_out]`, with `S′ = −30t²(1 − t)²/w` and `S″ = −60t(1 − t)(1 − 2t)/w²`
//! (`w = r_out − r_in`), which vanish at both ends. The distance split switches its
//! short-range part with it ([`super::distance_split`]) and the non-bonded term applies it
//! in its lanes ([`super::nonbonded::Nonbonded::switched`]); both import it from here.

/// The C² quintic switch from 1 at `r_in` to 0 at `r_out` (module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Switch {
    r_in: f64,
    r_out: f64,
    inverse_width: f64,
}

impl Switch {
    /// `0 < r_in < r_out`, both finite.
    pub fn new(r_in: f64, r_out: f64) -> Result<Self, String> {
        if !(r_in.is_finite() && r_out.is_finite()) {
            return Err(format!("r_in = {r_in} and r_out = {r_out} must be finite"));
        }
        if r_in <= 0.0 {
            return Err(format!("r_in = {r_in} must be positive"));
        }
        if r_in >= r_out {
            return Err(format!(
                "r_in = {r_in} must be smaller than r_out = {r_out} (the switch runs from 1 at \
                 r_in to 0 at r_out)"
            ));
        }
        Ok(Switch {
            r_in,
            r_out,
            inverse_width: 1.0 / (r_out - r_in),
        })
    }

    pub fn r_in(&self) -> f64 {
        self.r_in
    }

    pub fn r_out(&self) -> f64 {
        self.r_out
    }

    /// `1/(r_out − r_in)`.
    pub fn inverse_width(&self) -> f64 {
        self.inverse_width
    }

    /// `(S, S′)` at `r`.
    #[inline(always)]
    pub fn value_slope(&self, r: f64) -> (f64, f64) {
        // Clamped, not branched (t = 0 gives S = 1, S′ = 0 and t = 1 gives 0, 0 exactly), so
        // loops over it vectorise.
        let t = ((r - self.r_in) * self.inverse_width).clamp(0.0, 1.0);
        let u = 1.0 - t;
        // 1 − P(t) = P(1 − t) for the smoothstep P(t) = t³(10 − 15t + 6t²): each half
        // uses the form without cancellation at its end.
        let near = 1.0 - t * t * t * (10.0 - 15.0 * t + 6.0 * t * t);
        let far = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
        let s = if t < 0.5 { near } else { far };
        // 0 − x, not −x: +0 at the ends, as before.
        (s, (0.0 - 30.0 * t * t * u * u) * self.inverse_width)
    }

    /// `(S, S′, S″)` at `r`.
    #[inline(always)]
    pub fn derivatives(&self, r: f64) -> (f64, f64, f64) {
        let (s, s1) = self.value_slope(r);
        if r <= self.r_in || r >= self.r_out {
            return (s, s1, 0.0);
        }
        let t = (r - self.r_in) * self.inverse_width;
        let w2 = self.inverse_width * self.inverse_width;
        (s, s1, -60.0 * t * (1.0 - t) * (1.0 - 2.0 * t) * w2)
    }
}
