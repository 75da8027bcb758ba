//! A dwell design for CAD and spreadsheets: the six-bar at θ = 0 (pivots, joints, links
//! with their lengths) and its coupler curve, in user units (`scale` user units per
//! curve unit; the crank of the linkage itself is 1 curve unit). Written as JSON, CSV or
//! ASCII DXF (AutoCAD R12: LINE, CIRCLE and TEXT entities on named layers, readable by
//! every CAD program that imports DXF).

use crate::motion::Driver;
use crate::stage::{Stage, dyad_point};
use crate::{DwellDesign, DwellKind};
use serde::Serialize;
use std::fmt::Write as _;

/// A named point (a ground pivot or a moving joint), user units.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Joint {
    /// Name (O2, O4, O6; A crank pin, B rocker pin, M coupler point, D).
    pub name: &'static str,
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
}

/// A link (or one side of the ternary coupler), user units.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Link {
    /// Norton's link number (1 is the frame).
    pub number: u8,
    /// What it is.
    pub name: &'static str,
    /// Joint at one end.
    pub from: &'static str,
    /// Joint at the other end.
    pub to: &'static str,
    /// Length.
    pub length: f64,
}

/// The export formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExportFormat {
    /// JSON (everything).
    Json,
    /// CSV: one row per pivot, joint and link.
    Csv,
    /// ASCII DXF R12.
    Dxf,
}

impl ExportFormat {
    /// From a file name's extension (`.json`, `.csv`, `.dxf`, any case).
    pub fn from_path(path: &std::path::Path) -> Option<ExportFormat> {
        match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
            "json" => Some(ExportFormat::Json),
            "csv" => Some(ExportFormat::Csv),
            "dxf" => Some(ExportFormat::Dxf),
            _ => None,
        }
    }
}

/// The six-bar at θ = 0 in user units.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Export {
    /// What the numbers are in (e.g. "mm", or "crank" for crank units).
    pub units: String,
    /// User units per curve unit.
    pub scale: f64,
    /// The crank's length in user units.
    pub crank_length: f64,
    /// The crank angle drawn, degrees.
    pub theta_deg: f64,
    /// The kind of dwell.
    pub kind: DwellKind,
    /// Ground pivots O2, O4, O6.
    pub pivots: Vec<Joint>,
    /// Moving joints A, B, M, D (for the slot: no D; the block is at M).
    pub joints: Vec<Joint>,
    /// Links and their lengths.
    pub links: Vec<Link>,
    /// Where link 5's end dwells (the slot's pivot for a double dwell on lines).
    pub dwell_points: Vec<[f64; 2]>,
    /// The coupler curve, every simulation step, user units.
    pub curve: Vec<[f64; 2]>,
}

impl Export {
    /// The design at θ = 0, `scale` user units per curve unit, named `units`.
    pub fn new(design: &DwellDesign, driver: &Driver, scale: f64, units: &str) -> Option<Export> {
        let s = driver.state(0.0)?;
        let [o2, o4] = driver.pivots();
        let o6 = design.stage.pivot();
        let p = |name: &'static str, q: [f64; 2]| Joint {
            name,
            x: scale * q[0],
            y: scale * q[1],
        };
        let dist = |a: [f64; 2], b: [f64; 2]| scale * (a[0] - b[0]).hypot(a[1] - b[1]);
        let mut joints = vec![p("A", s.crank_pin), p("B", s.rocker_pin), p("M", s.m)];
        let mut links = vec![
            Link {
                number: 1,
                name: "frame O2–O4",
                from: "O2",
                to: "O4",
                length: dist(o2, o4),
            },
            Link {
                number: 2,
                name: "crank",
                from: "O2",
                to: "A",
                length: dist(o2, s.crank_pin),
            },
            Link {
                number: 3,
                name: "coupler",
                from: "A",
                to: "B",
                length: dist(s.crank_pin, s.rocker_pin),
            },
            Link {
                number: 3,
                name: "coupler, crank pin to coupler point",
                from: "A",
                to: "M",
                length: dist(s.crank_pin, s.m),
            },
            Link {
                number: 3,
                name: "coupler, rocker pin to coupler point",
                from: "B",
                to: "M",
                length: dist(s.rocker_pin, s.m),
            },
            Link {
                number: 4,
                name: "rocker",
                from: "O4",
                to: "B",
                length: dist(o4, s.rocker_pin),
            },
        ];
        match design.stage {
            Stage::Rocker {
                link5,
                link6,
                pivot,
                branch,
            } => {
                let d = dyad_point(s.m, link5, pivot, link6, branch)?;
                joints.push(p("D", d));
                links.push(Link {
                    number: 5,
                    name: "link 5",
                    from: "M",
                    to: "D",
                    length: scale * link5,
                });
                links.push(Link {
                    number: 6,
                    name: "output rocker",
                    from: "O6",
                    to: "D",
                    length: scale * link6,
                });
            }
            Stage::Slot { .. } => {
                links.push(Link {
                    number: 6,
                    name: "slotted output link (slot reach: the block's farthest distance from O6)",
                    from: "O6",
                    to: "M",
                    length: scale * design.farthest_reach.value,
                });
            }
        }
        links.push(Link {
            number: 1,
            name: "frame O2–O6",
            from: "O2",
            to: "O6",
            length: dist(o2, o6),
        });
        let mut curve = Vec::with_capacity(design.theta_deg.len());
        for &t in &design.theta_deg {
            let m = driver.state(t)?.m;
            curve.push([scale * m[0], scale * m[1]]);
        }
        Some(Export {
            units: units.to_string(),
            scale,
            crank_length: scale * driver.crank(),
            theta_deg: 0.0,
            kind: design.kind,
            pivots: vec![p("O2", o2), p("O4", o4), p("O6", o6)],
            joints,
            links,
            dwell_points: design
                .dwells
                .iter()
                .map(|d| [scale * d.point[0], scale * d.point[1]])
                .collect(),
            curve,
        })
    }

    /// The export in `format`.
    pub fn write(&self, format: ExportFormat) -> String {
        match format {
            ExportFormat::Json => {
                let mut s = serde_json::to_string_pretty(self).expect("export serialises");
                s.push('\n');
                s
            }
            ExportFormat::Csv => self.csv(),
            ExportFormat::Dxf => self.dxf(),
        }
    }

    fn find(&self, name: &str) -> Option<&Joint> {
        self.pivots
            .iter()
            .chain(&self.joints)
            .find(|j| j.name == name)
    }

    /// CSV: `element,name,x,y,length,from,to,units`, one row per pivot, joint and link.
    pub fn csv(&self) -> String {
        let mut s = String::from("element,name,x,y,length,from,to,units\n");
        for (kind, list) in [("pivot", &self.pivots), ("joint", &self.joints)] {
            for j in list {
                let _ = writeln!(s, "{kind},{},{},{},,,,{}", j.name, j.x, j.y, self.units);
            }
        }
        for l in &self.links {
            let _ = writeln!(
                s,
                "link,\"{} {}\",,,{},{},{},{}",
                l.number, l.name, l.length, l.from, l.to, self.units
            );
        }
        s
    }

    /// ASCII DXF (AutoCAD R12, `$ACADVER AC1009`): layers PIVOTS (circles at O2, O4, O6),
    /// JOINTS (circles at A, B, M, D), LINKS (a LINE per link), CURVE (the coupler curve as
    /// LINEs), DWELL (circles where D dwells) and LABELS (TEXT naming every pivot and
    /// joint). Joint circles have a radius of 3 % of the crank.
    pub fn dxf(&self) -> String {
        let mut s = String::new();
        let pair = |s: &mut String, code: i32, value: &str| {
            let _ = write!(s, "{code:>3}\r\n{value}\r\n");
        };
        let num = |x: f64| format!("{x}");
        let layers = [
            ("PIVOTS", 1),
            ("JOINTS", 5),
            ("LINKS", 7),
            ("CURVE", 3),
            ("DWELL", 6),
            ("LABELS", 7),
        ];
        pair(&mut s, 999, "coupler-atlas dwell design");
        pair(&mut s, 0, "SECTION");
        pair(&mut s, 2, "HEADER");
        pair(&mut s, 9, "$ACADVER");
        pair(&mut s, 1, "AC1009");
        pair(&mut s, 0, "ENDSEC");
        pair(&mut s, 0, "SECTION");
        pair(&mut s, 2, "TABLES");
        pair(&mut s, 0, "TABLE");
        pair(&mut s, 2, "LTYPE");
        pair(&mut s, 70, "1");
        pair(&mut s, 0, "LTYPE");
        pair(&mut s, 2, "CONTINUOUS");
        pair(&mut s, 70, "0");
        pair(&mut s, 3, "Solid line");
        pair(&mut s, 72, "65");
        pair(&mut s, 73, "0");
        pair(&mut s, 40, "0.0");
        pair(&mut s, 0, "ENDTAB");
        pair(&mut s, 0, "TABLE");
        pair(&mut s, 2, "LAYER");
        pair(&mut s, 70, &layers.len().to_string());
        for (name, color) in layers {
            pair(&mut s, 0, "LAYER");
            pair(&mut s, 2, name);
            pair(&mut s, 70, "0");
            pair(&mut s, 62, &color.to_string());
            pair(&mut s, 6, "CONTINUOUS");
        }
        pair(&mut s, 0, "ENDTAB");
        pair(&mut s, 0, "ENDSEC");
        pair(&mut s, 0, "SECTION");
        pair(&mut s, 2, "ENTITIES");
        let line = |s: &mut String, layer: &str, a: [f64; 2], b: [f64; 2]| {
            pair(s, 0, "LINE");
            pair(s, 8, layer);
            pair(s, 10, &num(a[0]));
            pair(s, 20, &num(a[1]));
            pair(s, 30, "0.0");
            pair(s, 11, &num(b[0]));
            pair(s, 21, &num(b[1]));
            pair(s, 31, "0.0");
        };
        let circle = |s: &mut String, layer: &str, c: [f64; 2], r: f64| {
            pair(s, 0, "CIRCLE");
            pair(s, 8, layer);
            pair(s, 10, &num(c[0]));
            pair(s, 20, &num(c[1]));
            pair(s, 30, "0.0");
            pair(s, 40, &num(r));
        };
        let text = |s: &mut String, at: [f64; 2], h: f64, t: &str| {
            pair(s, 0, "TEXT");
            pair(s, 8, "LABELS");
            pair(s, 10, &num(at[0]));
            pair(s, 20, &num(at[1]));
            pair(s, 30, "0.0");
            pair(s, 40, &num(h));
            pair(s, 1, t);
        };
        let r = 0.03 * self.crank_length;
        for j in &self.pivots {
            circle(&mut s, "PIVOTS", [j.x, j.y], r);
            text(&mut s, [j.x + 1.5 * r, j.y + 1.5 * r], 2.0 * r, j.name);
        }
        for j in &self.joints {
            circle(&mut s, "JOINTS", [j.x, j.y], r);
            text(&mut s, [j.x + 1.5 * r, j.y + 1.5 * r], 2.0 * r, j.name);
        }
        for l in &self.links {
            if l.number == 1 {
                continue; // the frame is the pivots
            }
            if let (Some(a), Some(b)) = (self.find(l.from), self.find(l.to)) {
                line(&mut s, "LINKS", [a.x, a.y], [b.x, b.y]);
            }
        }
        for w in self.curve.windows(2) {
            line(&mut s, "CURVE", w[0], w[1]);
        }
        for &d in &self.dwell_points {
            circle(&mut s, "DWELL", d, 0.5 * r);
        }
        pair(&mut s, 0, "ENDSEC");
        pair(&mut s, 0, "EOF");
        s
    }
}
