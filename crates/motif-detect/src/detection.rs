//! Building-block detection results and ground-truth annotations: the JSON schema of
//! `../shared/formats/detection.md`, written by `motif detect` and read by `motif eval`.
//!
//! A [`DetectionResult`] is a list of classes (thesis 5.5.2: 𝐃ʲ for a detection, 𝐆ⁱ for a
//! ground truth), each a list of instances given by an axis-aligned bounding box in world
//! coordinates. Ground-truth files use the same schema.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{DetectError, Result};

/// One scene's detected (or annotated) building blocks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectionResult {
    /// The scanned scene the classes belong to, e.g. `"scene_03.ply"`.
    pub scene: String,
    /// The building-block classes; may be empty (nothing detected).
    pub classes: Vec<DetectedClass>,
}

/// One class of building blocks: instances that are repetitions of the same template.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectedClass {
    /// Optional class name (`"window"`; detections may use `"class_0"`, ...).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The class's instances; at least one.
    pub instances: Vec<DetectedInstance>,
}

/// One instance of a class.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectedInstance {
    /// Minimum corner of the axis-aligned box, world coordinates.
    pub bbox_min: [f64; 3],
    /// Maximum corner of the axis-aligned box, world coordinates; `bbox_min[k] <= bbox_max[k]`.
    pub bbox_max: [f64; 3],
    /// Optional `instance_from_template`: maps the class template (instance 0, canonical pose)
    /// onto this instance; row-major 4 × 4 homogeneous matrix.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transform: Option<[[f64; 4]; 4]>,
    /// Optional indices of the input points belonging to this instance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub points: Option<Vec<u32>>,
}

impl DetectedInstance {
    /// An instance with only its bounding box.
    pub fn from_box(bbox_min: [f64; 3], bbox_max: [f64; 3]) -> Self {
        Self { bbox_min, bbox_max, transform: None, points: None }
    }

    /// Volume of the bounding box (0 for a flat or degenerate box).
    pub fn volume(&self) -> f64 {
        (0..3).map(|k| (self.bbox_max[k] - self.bbox_min[k]).max(0.0)).product()
    }
}

impl DetectedClass {
    /// A class without a name from its instances.
    pub fn new(instances: Vec<DetectedInstance>) -> Self {
        Self { name: None, instances }
    }
}

impl DetectionResult {
    /// Total number of instances over all classes (Σⱼ |𝐃ʲ| in thesis eq. 5.5).
    pub fn instance_count(&self) -> usize {
        self.classes.iter().map(|c| c.instances.len()).sum()
    }

    /// Checks that every value is usable for scoring: finite coordinates, `bbox_min <= bbox_max`
    /// per axis, finite transforms, and no class without instances. `origin` names the source
    /// (a file path, or `<memory>`) in the error, which also names the bad field.
    pub fn validate(&self, origin: &str) -> Result<()> {
        let bad = |field: String, problem: String| DetectError::Invalid {
            origin: origin.to_string(),
            field,
            problem,
        };
        for (c, class) in self.classes.iter().enumerate() {
            if class.instances.is_empty() {
                return Err(bad(
                    format!("classes[{c}].instances"),
                    "the class has no instances; remove the class or add its instances".into(),
                ));
            }
            for (i, inst) in class.instances.iter().enumerate() {
                let at = format!("classes[{c}].instances[{i}]");
                for (name, corner) in [("bbox_min", &inst.bbox_min), ("bbox_max", &inst.bbox_max)] {
                    for (k, v) in corner.iter().enumerate() {
                        if !v.is_finite() {
                            return Err(bad(
                                format!("{at}.{name}[{k}]"),
                                format!("{v} is not a finite number"),
                            ));
                        }
                    }
                }
                for k in 0..3 {
                    if inst.bbox_min[k] > inst.bbox_max[k] {
                        return Err(bad(
                            format!("{at}.bbox_min[{k}]"),
                            format!(
                                "bbox_min[{k}] = {} is greater than bbox_max[{k}] = {}; swap the corners",
                                inst.bbox_min[k], inst.bbox_max[k]
                            ),
                        ));
                    }
                }
                if let Some(t) = &inst.transform {
                    for (r, row) in t.iter().enumerate() {
                        for (k, v) in row.iter().enumerate() {
                            if !v.is_finite() {
                                return Err(bad(
                                    format!("{at}.transform[{r}][{k}]"),
                                    format!("{v} is not a finite number"),
                                ));
                            }
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// Parses and validates a detection or ground truth from JSON text; `origin` names the
    /// source in errors.
    ///
    /// A value of the wrong type or shape is named by its field's JSON path, as [`Self::validate`]
    /// names bad values (`classes[0].instances[3].bbox_min`), instead of only by line and column;
    /// Rust's type names (`u32`, `f64`, `struct DetectionResult`) are said in words.
    pub fn from_json_str(text: &str, origin: &Path) -> Result<Self> {
        let origin_text = origin.display().to_string();
        if !text.trim_start().starts_with('{') && serde_json::from_str::<serde_json::Value>(text).is_ok() {
            return Err(DetectError::InvalidInput(format!(
                "{origin_text}: not a detection/ground-truth JSON file: it holds no object, but a detection is an \
                 object with a \"classes\" list (../shared/formats/detection.md)"
            )));
        }
        let de = &mut serde_json::Deserializer::from_str(text);
        let result: Self = match serde_path_to_error::deserialize(de) {
            Ok(r) => r,
            Err(e) => {
                let field = e.path().to_string();
                let source = e.into_inner();
                // Syntax errors (a cut file) are the file's, not a field's.
                if field.is_empty() || field == "." || !source.is_data() {
                    return Err(DetectError::Json { path: origin.to_path_buf(), source });
                }
                // `motif detect --json` writes a report whose `classes` is a count.
                let report = field == "classes"
                    && ["\"options\"", "\"seconds\"", "\"report\""].iter().all(|k| text.contains(k));
                let hint = if report {
                    " (this looks like the report of `motif detect --json`; give the result it wrote with -o)"
                } else {
                    ""
                };
                return Err(DetectError::Invalid {
                    origin: origin_text,
                    field,
                    problem: format!("{}{hint}", plain_serde_message(&source.to_string())),
                });
            }
        };
        result.validate(&origin.display().to_string())?;
        Ok(result)
    }

    /// Reads and validates a detection or ground-truth file.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| DetectError::Io { path: path.to_path_buf(), source })?;
        Self::from_json_str(&text, path)
    }

    /// Validates and writes this result to `path` as pretty-printed JSON, atomically
    /// ([`motif_core::io::write_atomic`]).
    pub fn write(&self, path: &Path) -> Result<()> {
        self.validate(&path.display().to_string())?;
        let text = serde_json::to_string_pretty(self)
            .map_err(|source| DetectError::Json { path: path.to_path_buf(), source })?;
        motif_core::io::write_atomic(path, |w| {
            w.write_all(text.as_bytes())?;
            w.write_all(b"\n")
        })?;
        Ok(())
    }
}

/// serde's message with Rust's type names in words: `expected u32` → "expected a whole number
/// (0 or more)", `expected f64` → "expected a number", `struct Instance` → "an object".
fn plain_serde_message(msg: &str) -> String {
    let mut out = msg
        .replace("expected u32", "expected a whole number (0 or more)")
        .replace("expected u64", "expected a whole number (0 or more)")
        .replace("expected usize", "expected a whole number (0 or more)")
        .replace("expected f64", "expected a number")
        .replace("expected f32", "expected a number");
    while let Some(i) = out.find("struct ") {
        let rest = &out[i + "struct ".len()..];
        let name_len = rest.bytes().take_while(|b| b.is_ascii_alphanumeric() || *b == b'_').count();
        out = format!("{}an object{}", &out[..i], &rest[name_len..]);
    }
    out
}
