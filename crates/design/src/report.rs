//! A dwell design in words: the lines `dwell` prints, and the card's box repeats.

use crate::stage::Stage;
use crate::{DwellDesign, DwellKind};

fn f4(x: f64) -> String {
    format!("{x:.4}")
}

fn pt(p: [f64; 2]) -> String {
    format!("({}, {})", f4(p[0]), f4(p[1]))
}

impl DwellDesign {
    /// The four-bar in words.
    pub fn driver_text(&self) -> String {
        let d = &self.driver;
        let base = format!(
            "{} ({}), point ({}, {})",
            d.curve_linkage,
            d.curve_circuit.name(),
            d.curve_point.u,
            d.curve_point.v
        );
        if d.cognate == 0 {
            format!("four-bar {base}")
        } else {
            let [c, a, b, g] = d.links;
            format!(
                "four-bar: cognate {} of {base}: pivots {} and {}, crank {}, coupler {}, rocker {}, ground {}, point ({}, {}) ({}); crank 1: A = {}, B = {}, C = {}",
                d.cognate,
                pt(d.pivots[0]),
                pt(d.pivots[1]),
                f4(c),
                f4(a),
                f4(b),
                f4(g),
                f4(d.point[0]),
                f4(d.point[1]),
                d.circuit.name(),
                f4(d.normalized[0]),
                f4(d.normalized[1]),
                f4(d.normalized[2])
            )
        }
    }

    /// Links 5 and 6 in words.
    pub fn stage_text(&self) -> String {
        match self.stage {
            Stage::Rocker {
                link5,
                link6,
                pivot,
                ..
            } => format!(
                "link 5 (M–D) {}, link 6 (O6–D) {}, O6 {}; link ratio {:.2} : 1 (bound {} : 1)",
                f4(link5),
                f4(link6),
                pt(pivot),
                self.link_ratio,
                self.limits.max_link_ratio
            ),
            Stage::Slot { pivot } => format!(
                "link 5: a block pinned to the coupler at M, sliding in link 6; link 6: slotted, pivoted at O6 {}; the block stays {}–{} from O6 (reach ratio {:.2} : 1, bound {} : 1)",
                pt(pivot),
                f4(self.closest_approach.value),
                f4(self.farthest_reach.value),
                self.link_ratio,
                self.limits.max_link_ratio
            ),
        }
    }

    /// The transmission angles in words.
    pub fn transmission_text(&self) -> String {
        let [c, e] = self.fourbar_transmission_range_deg;
        match self.output_transmission_range_deg {
            Some([a, b]) => format!(
                "transmission angles over the revolution: links 5–6 {a:.2}°–{b:.2}° (limit {}°–{}°), four-bar {c:.2}°–{e:.2}°",
                self.limits.min_transmission_deg,
                180.0 - self.limits.min_transmission_deg
            ),
            None => format!(
                "transmission angles: links 5–6 90° by construction (the block pushes square to the slot, and link 6 moves square to it there: no limit applies; what limits a slot is the block's approach to O6), four-bar {c:.2}°–{e:.2}°"
            ),
        }
    }

    /// Every line `dwell` prints (table format), `asked` the swing asked for.
    pub fn report_lines(&self, asked: Option<f64>) -> Vec<String> {
        let mut v = Vec::new();
        let mut head = self.kind.describe().to_string();
        if let Some(first) = head.get(..1) {
            head = first.to_uppercase() + &head[1..];
        }
        v.push(format!("{head}; {}", self.method.describe()));
        v.push(self.driver_text());
        v.push(self.stage_text());
        v.push(format!("dyad branch: {}", self.branch_text()));
        let [lo, hi] = self.output_range_deg;
        let mut swing = format!(
            "output ψ from {lo:.3}° to {hi:.3}°: swing {:.3}°",
            self.swing_deg
        );
        if let Some(s) = self.dwell_swing_deg {
            swing += &format!(", between the dwells {s:.3}°");
        }
        if let Some(a) = asked {
            swing += &format!(" (asked for {a}°)");
        }
        v.push(swing);
        for (k, x) in self.dwells.iter().enumerate() {
            let what = match self.kind {
                DwellKind::DoubleLines => "slot pivot",
                _ => "D dwells at",
            };
            v.push(format!(
                "dwell {}: window θ {}°–{}° ({}° of crank, {} dashes of 10°), {what} {}, mean output {:.3}°, jitter {:.4}°",
                k + 1,
                fmt_deg(x.start_deg),
                fmt_deg(x.start_deg + x.span_deg),
                fmt_deg(x.span_deg),
                (x.span_deg / 10.0 + 1e-9).floor(),
                pt(x.point),
                x.output_deg,
                x.jitter_deg
            ));
            let felt = &x.felt;
            v.push(format!(
                "  felt: within ±{}° of {:.3}° for {}° of crank (θ {}°–{}°, samples every {}°)",
                felt.tol_deg,
                felt.position_deg,
                fmt_deg(felt.span_deg),
                fmt_deg(felt.start_deg),
                fmt_deg((felt.start_deg + felt.span_deg) % 360.0),
                self.limits.step_deg
            ));
            if let Some([a, b]) = x.transmission_range_deg {
                v.push(format!(
                    "  links 5–6 transmission during it {a:.2}°–{b:.2}°"
                ));
            }
        }
        v.push(self.transmission_text());
        v.push(format!(
            "output speed (unit crank speed): peak |dψ/dθ| {:.4} rad/rad at θ = {:.2}°; peak |d²ψ/dθ²| {:.4} rad/rad² at θ = {:.2}°",
            self.peak_velocity.value,
            self.peak_velocity.theta_deg,
            self.peak_acceleration.value,
            self.peak_acceleration.theta_deg
        ));
        v.push(format!(
            "closest approach of the coupler point M to O6: {} at θ = {:.2}° (farthest {} at θ = {:.2}°)",
            f4(self.closest_approach.value),
            self.closest_approach.theta_deg,
            f4(self.farthest_reach.value),
            self.farthest_reach.theta_deg
        ));
        v.push(format!(
            "checked: transmission ≥ {}°, jitter ≤ {} % of the swing, link ratio ≤ {} : 1, oscillating output, one branch (simulated every {}°)",
            self.limits.min_transmission_deg,
            self.limits.max_jitter_pct,
            self.limits.max_link_ratio,
            self.limits.step_deg
        ));
        for n in &self.notes {
            v.push(format!("note: {n}"));
        }
        for w in &self.warnings {
            v.push(format!("warning: {w}"));
        }
        v
    }
}

/// Degrees without a trailing `.0` for whole numbers, else up to 3 decimals.
pub fn fmt_deg(x: f64) -> String {
    if (x - x.round()).abs() < 1e-9 {
        format!("{}", x.round())
    } else {
        let s = format!("{x:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}
