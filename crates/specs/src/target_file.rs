//! Reading target files from text: CSV and JSON lists of points. Pure (takes `&str`);
//! reading the file is the caller's. Errors name the line (and field) at fault.
//!
//! **CSV**: one point per line, `x,y` or `x,y,angle` (the input angle in degrees).
//! Separators: commas, semicolons, tabs or spaces. Blank lines and lines starting with
//! `#` are skipped. An optional header line names the columns: `x`, `y` and an angle
//! column `angle`, `angle_deg`, `theta` or `theta_deg` (in any order; other columns are
//! refused, so a typo does not silently drop data).
//!
//! **JSON**: either a bare array of points, `[[x, y], …]` or `[[x, y, angle], …]`, or an
//! object `{"points": [[x, y], …], "closed": true, "angles_deg": [...], "timing":
//! "equal_steps"}` whose keys other than `points` are optional. Points may also be
//! objects `{"x": …, "y": …, "angle_deg": …}`.

use serde::Deserialize;

/// A target file as read: points, per-point angles if every point has one, and what the
/// file says about closure and timing (the caller's flags may override).
#[derive(Clone, Debug, PartialEq)]
pub struct TargetFile {
    /// The points (x, y), in file order.
    pub points: Vec<[f64; 2]>,
    /// The input angle of each point in degrees, if the file gives them.
    pub angles_deg: Option<Vec<f64>>,
    /// `closed` from a JSON object, if present.
    pub closed: Option<bool>,
    /// `"timing": "equal_steps"` in a JSON object.
    pub equal_steps: bool,
}

/// Why a target file could not be read. Lines count from 1.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TargetFileError {
    /// A CSV line that is not a point.
    #[error("line {line}: {message}")]
    Csv {
        /// Line number.
        line: usize,
        /// What is wrong (naming the field).
        message: String,
    },
    /// JSON that is malformed or not of this shape.
    #[error("line {line}, column {column}: {message}")]
    Json {
        /// Line number.
        line: usize,
        /// Column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// Valid JSON whose content is wrong (naming the point).
    #[error("{0}")]
    Content(String),
    /// No points at all.
    #[error("the file holds no points")]
    Empty,
}

impl TargetFile {
    /// Reads a target file's text, CSV or JSON by the file's name: `.json` is JSON,
    /// anything else CSV (also `-`, standard input). See the module doc for the formats.
    pub fn parse(text: &str, name: &str) -> Result<TargetFile, TargetFileError> {
        if name.to_ascii_lowercase().ends_with(".json") {
            Self::from_json(text)
        } else {
            Self::from_csv(text)
        }
    }

    /// Reads CSV text. See the module doc for the format.
    ///
    /// ```
    /// use coupler_specs::TargetFile;
    /// let f = TargetFile::from_csv("x,y\n0,0\n1,0.5\n# a comment\n2,2\n").unwrap();
    /// assert_eq!(f.points, vec![[0.0, 0.0], [1.0, 0.5], [2.0, 2.0]]);
    /// let e = TargetFile::from_csv("0,0\n1,zero\n").unwrap_err();
    /// assert_eq!(e.to_string(), "line 2: y: `zero` is not a number");
    /// ```
    pub fn from_csv(text: &str) -> Result<TargetFile, TargetFileError> {
        parse_csv(text)
    }

    /// Reads JSON text. See the module doc for the shapes accepted.
    ///
    /// ```
    /// use coupler_specs::TargetFile;
    /// let f = TargetFile::from_json(r#"{"points": [[0, 0], [1, 0], [1, 1]], "closed": false}"#).unwrap();
    /// assert_eq!(f.points.len(), 3);
    /// assert_eq!(f.closed, Some(false));
    /// ```
    pub fn from_json(text: &str) -> Result<TargetFile, TargetFileError> {
        parse_json(text)
    }
}

fn parse_csv(text: &str) -> Result<TargetFile, TargetFileError> {
    let mut columns: Option<Vec<Column>> = None;
    let mut points = Vec::new();
    let mut angles: Vec<f64> = Vec::new();
    let mut with_angle: Option<bool> = None;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let trimmed = raw.trim().trim_start_matches('\u{feff}');
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = trimmed
            .split([',', ';', '\t', ' '])
            .filter(|f| !f.is_empty())
            .collect();
        if columns.is_none()
            && points.is_empty()
            && fields.iter().any(|f| f.parse::<f64>().is_err())
        {
            columns = Some(header(&fields, line)?);
            continue;
        }
        let cols = columns.get_or_insert_with(|| match fields.len() {
            3 => vec![Column::X, Column::Y, Column::Angle],
            _ => vec![Column::X, Column::Y],
        });
        if fields.len() != cols.len() {
            return Err(TargetFileError::Csv {
                line,
                message: format!(
                    "expected {} fields ({}), found {}",
                    cols.len(),
                    cols.iter().map(|c| c.name()).collect::<Vec<_>>().join(", "),
                    fields.len()
                ),
            });
        }
        let (mut x, mut y, mut a) = (0.0, 0.0, None);
        for (f, c) in fields.iter().zip(cols.iter()) {
            let v: f64 = f.parse().map_err(|_| TargetFileError::Csv {
                line,
                message: format!("{}: `{f}` is not a number", c.name()),
            })?;
            if !v.is_finite() {
                return Err(TargetFileError::Csv {
                    line,
                    message: format!("{}: `{f}` is not a finite number", c.name()),
                });
            }
            match c {
                Column::X => x = v,
                Column::Y => y = v,
                Column::Angle => a = Some(v),
            }
        }
        points.push([x, y]);
        if let Some(a) = a {
            angles.push(a);
        }
        with_angle = Some(cols.contains(&Column::Angle));
    }
    if points.is_empty() {
        return Err(TargetFileError::Empty);
    }
    Ok(TargetFile {
        points,
        angles_deg: (with_angle == Some(true)).then_some(angles),
        closed: None,
        equal_steps: false,
    })
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Column {
    X,
    Y,
    Angle,
}

impl Column {
    fn name(self) -> &'static str {
        match self {
            Column::X => "x",
            Column::Y => "y",
            Column::Angle => "angle",
        }
    }
}

fn header(fields: &[&str], line: usize) -> Result<Vec<Column>, TargetFileError> {
    let mut cols = Vec::new();
    for f in fields {
        let c = match f.trim_matches('"').to_ascii_lowercase().as_str() {
            "x" => Column::X,
            "y" => Column::Y,
            "angle" | "angle_deg" | "theta" | "theta_deg" => Column::Angle,
            other => {
                return Err(TargetFileError::Csv {
                    line,
                    message: format!(
                        "unknown column `{other}` (expected x, y and optionally angle_deg)"
                    ),
                });
            }
        };
        if cols.contains(&c) {
            return Err(TargetFileError::Csv {
                line,
                message: format!("column `{}` given twice", c.name()),
            });
        }
        cols.push(c);
    }
    if !(cols.contains(&Column::X) && cols.contains(&Column::Y)) {
        return Err(TargetFileError::Csv {
            line,
            message: "the header must name columns x and y".into(),
        });
    }
    Ok(cols)
}

#[derive(Deserialize)]
#[serde(untagged)]
enum JsonPoint {
    Pair([f64; 2]),
    Triple([f64; 3]),
    Object {
        x: f64,
        y: f64,
        #[serde(default, alias = "angle")]
        angle_deg: Option<f64>,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct JsonObject {
    points: Vec<JsonPoint>,
    #[serde(default)]
    closed: Option<bool>,
    #[serde(default)]
    angles_deg: Option<Vec<f64>>,
    #[serde(default)]
    timing: Option<JsonTiming>,
}

#[derive(Deserialize, PartialEq)]
#[serde(rename_all = "snake_case")]
enum JsonTiming {
    Untimed,
    EqualSteps,
    Angles,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum JsonTarget {
    List(Vec<JsonPoint>),
    Object(JsonObject),
}

fn parse_json(text: &str) -> Result<TargetFile, TargetFileError> {
    // Parse to a value first so that syntax errors carry their line and column.
    let value: serde_json::Value =
        serde_json::from_str(text).map_err(|e| TargetFileError::Json {
            line: e.line(),
            column: e.column(),
            message: e.to_string(),
        })?;
    let target: JsonTarget = serde_json::from_value(value).map_err(|e| {
        TargetFileError::Content(format!(
            "expected an array of points [[x, y], …] or an object {{\"points\": […], \"closed\", \"angles_deg\", \"timing\"}}: {e}"
        ))
    })?;
    let (list, closed, given_angles, timing) = match target {
        JsonTarget::List(l) => (l, None, None, None),
        JsonTarget::Object(o) => (o.points, o.closed, o.angles_deg, o.timing),
    };
    if list.is_empty() {
        return Err(TargetFileError::Empty);
    }
    let mut points = Vec::with_capacity(list.len());
    let mut inline: Vec<Option<f64>> = Vec::with_capacity(list.len());
    for p in list {
        match p {
            JsonPoint::Pair([x, y]) => {
                points.push([x, y]);
                inline.push(None);
            }
            JsonPoint::Triple([x, y, a]) => {
                points.push([x, y]);
                inline.push(Some(a));
            }
            JsonPoint::Object { x, y, angle_deg } => {
                points.push([x, y]);
                inline.push(angle_deg);
            }
        }
    }
    let with = inline.iter().filter(|a| a.is_some()).count();
    if with != 0 && with != inline.len() {
        let k = inline.iter().position(|a| a.is_none()).unwrap_or(0);
        return Err(TargetFileError::Content(format!(
            "point {k} has no angle while {with} others have one: give every point an angle or none"
        )));
    }
    let angles_deg = match (given_angles, with > 0) {
        (Some(_), true) => {
            return Err(TargetFileError::Content(
                "angles given twice: both in the points and in \"angles_deg\"".into(),
            ));
        }
        (Some(a), false) => Some(a),
        (None, true) => Some(inline.into_iter().flatten().collect()),
        (None, false) => None,
    };
    if timing == Some(JsonTiming::Angles) && angles_deg.is_none() {
        return Err(TargetFileError::Content(
            "\"timing\": \"angles\" but no point has an angle".into(),
        ));
    }
    if timing == Some(JsonTiming::EqualSteps) && angles_deg.is_some() {
        return Err(TargetFileError::Content(
            "\"timing\": \"equal_steps\" with angles: choose one".into(),
        ));
    }
    Ok(TargetFile {
        points,
        angles_deg: if timing == Some(JsonTiming::Untimed) {
            None
        } else {
            angles_deg
        },
        closed,
        equal_steps: timing == Some(JsonTiming::EqualSteps),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_forms_and_errors() {
        let f = parse_csv("1 2\n3 4\n5 6\n").unwrap();
        assert_eq!(f.points, vec![[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]]);
        assert_eq!(f.angles_deg, None);
        let f = parse_csv("angle_deg;y;x\n0;1;2\n10;3;4\n").unwrap();
        assert_eq!(f.points, vec![[2.0, 1.0], [4.0, 3.0]]);
        assert_eq!(f.angles_deg, Some(vec![0.0, 10.0]));
        let f = parse_csv("0,0,0\n1,1,5\n").unwrap();
        assert_eq!(f.angles_deg, Some(vec![0.0, 5.0]));
        let e = parse_csv("x,y\n0,0\n1,1,1\n").unwrap_err();
        assert_eq!(e.to_string(), "line 3: expected 2 fields (x, y), found 3");
        let e = parse_csv("x,why\n").unwrap_err();
        assert!(e.to_string().contains("unknown column `why`"), "{e}");
        let e = parse_csv("0,0\n1,inf\n").unwrap_err();
        assert_eq!(e.to_string(), "line 2: y: `inf` is not a finite number");
        assert_eq!(parse_csv("# nothing\n\n"), Err(TargetFileError::Empty));
        let e = parse_csv("x,x\n").unwrap_err();
        assert!(e.to_string().contains("twice"), "{e}");
    }

    #[test]
    fn json_forms_and_errors() {
        let f = parse_json("[[0,0],[1,2]]").unwrap();
        assert_eq!(f.points, vec![[0.0, 0.0], [1.0, 2.0]]);
        let f = parse_json("[[0,0,5],[1,2,15]]").unwrap();
        assert_eq!(f.angles_deg, Some(vec![5.0, 15.0]));
        let f = parse_json(
            r#"{"points":[{"x":1,"y":2,"angle_deg":3},{"x":4,"y":5,"angle_deg":6}],"closed":true}"#,
        )
        .unwrap();
        assert_eq!(f.points, vec![[1.0, 2.0], [4.0, 5.0]]);
        assert_eq!((f.angles_deg, f.closed), (Some(vec![3.0, 6.0]), Some(true)));
        let f = parse_json(r#"{"points":[[0,0],[1,1]],"timing":"equal_steps"}"#).unwrap();
        assert!(f.equal_steps);
        let e = parse_json("[[0,0],\n[1,]]").unwrap_err();
        assert!(matches!(e, TargetFileError::Json { line: 2, .. }), "{e}");
        let e = parse_json("[[0,0,1],[1,1]]").unwrap_err();
        assert!(e.to_string().contains("point 1 has no angle"), "{e}");
        let e = parse_json(r#"{"points":[[0,0]],"colour":"red"}"#).unwrap_err();
        assert!(e.to_string().contains("expected an array"), "{e}");
        assert_eq!(parse_json("[]"), Err(TargetFileError::Empty));
    }
}
