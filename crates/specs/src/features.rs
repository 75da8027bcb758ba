//! The `[features]` table of a grid spec: whether the index carries features, and the
//! extraction tolerances ([`FeatureTolerances`]).

use coupler_features::FeatureTolerances;
use serde::Serialize;

/// The `[features]` table of a spec: whether the index carries features, and the
/// tolerances. Every key is optional:
///
/// ```toml
/// [features]
/// enabled = true        # default true
/// straight_pct = 0.5    # any FeatureTolerances field
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FeatureSettings {
    /// Extract features into the index (true).
    pub enabled: bool,
    /// The tolerances.
    #[serde(flatten)]
    pub tolerances: FeatureTolerances,
}

impl FeatureSettings {
    /// Features on, default tolerances.
    pub const DEFAULT: FeatureSettings = FeatureSettings {
        enabled: true,
        tolerances: FeatureTolerances::DEFAULT,
    };

    /// Reads a `[features]` table (`enabled` plus [`FeatureTolerances`] fields) and
    /// validates it. The error names the offending key.
    pub fn from_table(table: &toml::Table) -> Result<FeatureSettings, String> {
        let mut rest = table.clone();
        let enabled = match rest.remove("enabled") {
            None => true,
            Some(toml::Value::Boolean(b)) => b,
            Some(v) => return Err(format!("features.enabled must be true or false, got {v}")),
        };
        let tolerances: FeatureTolerances = toml::Value::Table(rest)
            .try_into()
            .map_err(|e: toml::de::Error| format!("in [features]: {}", e.message()))?;
        tolerances.validate()?;
        coupler_kinematics::samples_per_turn(tolerances.step_deg)
            .map_err(|m| format!("features.step_deg: {m}"))?;
        Ok(FeatureSettings {
            enabled,
            tolerances,
        })
    }
}

impl Default for FeatureSettings {
    fn default() -> Self {
        FeatureSettings::DEFAULT
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_from_toml() {
        let t: toml::Table = toml::from_str("enabled = false\nstraight_pct = 1.5").unwrap();
        let s = FeatureSettings::from_table(&t).unwrap();
        assert!(!s.enabled);
        assert_eq!(s.tolerances.straight_pct, 1.5);
        assert_eq!(s.tolerances.arc_pct, FeatureTolerances::DEFAULT.arc_pct);
        let bad: toml::Table = toml::from_str("straight = 1.5").unwrap();
        assert!(
            FeatureSettings::from_table(&bad)
                .unwrap_err()
                .contains("straight")
        );
        let bad: toml::Table = toml::from_str("step_deg = 7").unwrap();
        assert!(
            FeatureSettings::from_table(&bad)
                .unwrap_err()
                .contains("step_deg")
        );
    }
}
