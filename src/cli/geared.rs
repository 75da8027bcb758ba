//! `coupler-atlas curve --mechanism geared-fivebar --l1 L1 --l3 L3 --l4 L4 --l5 L5
//! --ratio P[/Q] [--phase DEG] --point U,V [--circuit] [--step] [--trace] [--format]`:
//! the coupler curve of a geared five-bar (docs/geared-fivebar.md), sampled over the
//! mechanism's period, written by the four-bar's writer (`curve.rs`, [`CurveOutput`]).

use super::curve_output::{CurveOutput, Sample, finite};
use super::{UsageError, parse_length, parse_number};
use anyhow::Result;
use coupler_atlas::{
    Circuit, CouplerPoint, CrankTable, CurveFlags, FlagTolerances, GearRatio, GearedFiveBar,
    Mechanism, Rotatability, WindowMeasures,
};

/// The flags naming a geared five-bar (Norton's numbering; the input crank L2 = 1).
#[derive(clap::Args, Debug)]
pub struct GearedArgs {
    /// Geared five-bar: ground L1 (O2 to O5), in input-crank units.
    #[arg(long, value_parser = parse_length, allow_hyphen_values = true)]
    l1: Option<f64>,
    /// Geared five-bar: dyad link L3 from the input crank's pin (carries the coupler point).
    #[arg(long, value_parser = parse_length, allow_hyphen_values = true)]
    l3: Option<f64>,
    /// Geared five-bar: dyad link L4 from the second crank's pin.
    #[arg(long, value_parser = parse_length, allow_hyphen_values = true)]
    l4: Option<f64>,
    /// Geared five-bar: second crank L5 at O5.
    #[arg(long, value_parser = parse_length, allow_hyphen_values = true)]
    l5: Option<f64>,
    /// Geared five-bar: gear ratio λ = θ̇5/θ̇2 as `p` or `p/q` (negative for an external
    /// pair), e.g. `-1`, `2`, `-1/2`.
    #[arg(long, allow_hyphen_values = true)]
    ratio: Option<String>,
    /// Geared five-bar: phase φ in degrees, θ5 = λ·θ2 + φ.
    #[arg(long, default_value = "0", value_parser = parse_number, allow_hyphen_values = true)]
    phase: f64,
}

impl GearedArgs {
    /// Whether any geared five-bar flag other than `--phase` was given.
    pub fn any(&self) -> bool {
        self.l1.is_some()
            || self.l3.is_some()
            || self.l4.is_some()
            || self.l5.is_some()
            || self.ratio.is_some()
    }

    /// The validated linkage.
    pub fn resolve(&self) -> Result<GearedFiveBar, UsageError> {
        let need = |x: Option<f64>, flag: &str| {
            x.ok_or_else(|| {
                UsageError(format!(
                    "the geared five-bar needs --l1, --l3, --l4, --l5 and --ratio: {flag} is missing"
                ))
            })
        };
        let ratio_text = self.ratio.as_deref().ok_or_else(|| {
            UsageError(
                "the geared five-bar needs --l1, --l3, --l4, --l5 and --ratio: --ratio is missing"
                    .into(),
            )
        })?;
        let ratio: GearRatio = ratio_text
            .parse()
            .map_err(|e| UsageError(format!("--ratio: {e}")))?;
        GearedFiveBar::new(
            need(self.l1, "--l1")?,
            need(self.l3, "--l3")?,
            need(self.l4, "--l4")?,
            need(self.l5, "--l5")?,
            ratio,
            self.phase,
        )
        .map_err(|e| UsageError(e.to_string()))
    }
}

/// The `"linkage"` object and the mechanism's identity, as the JSON starts:
/// `{"mechanism":"geared-fivebar","linkage":{…}`.
pub fn json_head(linkage: &GearedFiveBar) -> Result<String> {
    Ok(format!(
        "{{\"mechanism\":\"geared-fivebar\",\"linkage\":{}",
        serde_json::to_string(linkage)?
    ))
}

fn rotatability_name(r: Rotatability) -> &'static str {
    match r {
        Rotatability::Full => "full",
        Rotatability::Touches => "touches_toggle",
        Rotatability::Limited => "rocks",
    }
}

/// One circuit sampled over the period every `step` degrees of input, as `curve`
/// writes it ([`CurveOutput`]): the four-bar's fields, and the second crank's angle
/// θ5 = λ·θ2 + φ (reduced to [0, 360)).
pub fn output(
    linkage: &GearedFiveBar,
    circuit: Circuit,
    p: CouplerPoint,
    step: f64,
    window: Option<WindowMeasures>,
) -> Result<CurveOutput<'static>> {
    let period = Mechanism::period_deg(linkage);
    let table = CrankTable::over(step, period).ok_or_else(|| {
        UsageError(format!(
            "--step must be > 0 and at most 360 degrees, got {step}"
        ))
    })?;
    let degrees: Vec<f64> = table.angles().iter().map(|a| a.degrees).collect();
    let flags = CurveFlags::assess_geared(linkage, circuit, p, &degrees, &FlagTolerances::DEFAULT);
    let samples: Vec<Sample> = table
        .angles()
        .iter()
        .map(|angle| {
            let theta5_deg = Some(linkage.angle_at(angle.degrees).second.degrees);
            match linkage.pose_at_angle(circuit, angle) {
                Some(pose) => {
                    let m = pose.point(p);
                    let v = pose.velocity(p);
                    let v = v.filter(|v| v.x.is_finite() && v.y.is_finite());
                    Sample {
                        theta_deg: angle.degrees,
                        theta5_deg,
                        x: finite(m.x),
                        y: finite(m.y),
                        vx: v.map(|v| v.x),
                        vy: v.map(|v| v.y),
                        transmission_deg: finite(pose.transmission.to_degrees()),
                    }
                }
                None => Sample {
                    theta_deg: angle.degrees,
                    theta5_deg,
                    x: None,
                    y: None,
                    vx: None,
                    vy: None,
                    transmission_deg: None,
                },
            }
        })
        .collect();
    let class = linkage.ting_class();
    Ok(CurveOutput {
        head: json_head(linkage)?,
        extra: format!(
            ",\"period_deg\":{},\"rotatability\":\"{}\"",
            serde_json::to_string(&period)?,
            rotatability_name(linkage.rotatability(coupler_atlas::MARGIN_TOL))
        ),
        title: format!("geared five-bar {linkage} ({class}, period {period}°)"),
        class: class.code(),
        circuit,
        point: p,
        samples,
        flags,
        window,
    })
}
