//! The bake sweep's samples CSV:
//! `object,g,p,size_bytes,gpu_bytes,quads,ssim,psnr,lpips`.
//!
//! The header names the columns (any order; extra columns are ignored).
//! `object`, `g`, `p`, `size_bytes` and `ssim` are required; `gpu_bytes`,
//! `quads`, `psnr` and `lpips` are optional and may be empty. Blank lines
//! and lines starting with `#` are skipped; fields may be double-quoted.
//! Every problem is reported with the file, the line number and the column,
//! e.g. `sweep.csv:7: ssim: expected a number, got "abc"`.

use nerflex_core::units::Bytes;
use std::collections::HashMap;
use std::fmt;
use std::path::Path;

/// The columns of a samples CSV, in the order written.
pub const COLUMNS: [&str; 9] = [
    "object",
    "g",
    "p",
    "size_bytes",
    "gpu_bytes",
    "quads",
    "ssim",
    "psnr",
    "lpips",
];

/// One measured bake: an object at one configuration (g, p).
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// Object name.
    pub object: String,
    /// Voxel grid resolution per axis.
    pub g: u32,
    /// Texel patch size per quad (p × p).
    pub p: u32,
    /// Baked data size (files on disk).
    pub size: Bytes,
    /// GPU-resident size, if measured.
    pub gpu: Option<Bytes>,
    /// Number of quads, if measured.
    pub quads: Option<u64>,
    /// Mean SSIM over the held-out views.
    pub ssim: f64,
    /// Mean PSNR (dB), if measured (`inf` allowed).
    pub psnr: Option<f64>,
    /// Mean LPIPS, if measured.
    pub lpips: Option<f64>,
    /// Line of the CSV file the sample came from (1-based; 0 if built in code).
    pub line: usize,
}

/// A problem in a samples CSV: file, line (1-based, 0 for the whole file),
/// column and what is wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SamplesError {
    /// The file as given.
    pub origin: String,
    /// Line number (1-based), 0 when the problem is not on one line.
    pub line: usize,
    /// Column name, empty when the problem is the whole line.
    pub column: String,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for SamplesError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.origin)?;
        if self.line > 0 {
            write!(f, ":{}", self.line)?;
        }
        if !self.column.is_empty() {
            write!(f, ": {}", self.column)?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for SamplesError {}

/// Reads and validates a samples CSV.
pub fn read(path: &Path) -> Result<Vec<Sample>, SamplesError> {
    let origin = path.display().to_string();
    let text = crate::validate::read_to_string(path).map_err(|e| SamplesError {
        origin: origin.clone(),
        line: 0,
        column: String::new(),
        message: format!("cannot read: {e}"),
    })?;
    parse(&text, &origin)
}

/// Parses and validates samples CSV text; `origin` names it in errors.
///
/// Rejects duplicate (object, g, p) rows, naming both lines.
pub fn parse(text: &str, origin: &str) -> Result<Vec<Sample>, SamplesError> {
    let err = |line: usize, column: &str, message: String| SamplesError {
        origin: origin.to_string(),
        line,
        column: column.to_string(),
        message,
    };
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim_end_matches('\r')))
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some((header_line, header)) = lines.next() else {
        return Err(err(0, "", "empty file: expected a header line".into()));
    };
    let names = split(header).map_err(|m| err(header_line, "", m))?;
    let mut index: HashMap<String, usize> = HashMap::new();
    for (i, n) in names.iter().enumerate() {
        if index.insert(n.trim().to_string(), i).is_some() {
            return Err(err(header_line, n.trim(), "column appears twice".into()));
        }
    }
    for name in ["object", "g", "p", "size_bytes", "ssim"] {
        if !index.contains_key(name) {
            return Err(err(
                header_line,
                "",
                format!(
                    "missing column {name:?} (expected a header like {})",
                    COLUMNS.join(",")
                ),
            ));
        }
    }
    let mut out = Vec::new();
    let mut seen: HashMap<(String, u32, u32), usize> = HashMap::new();
    for (line, text) in lines {
        let fields = split(text).map_err(|m| err(line, "", m))?;
        if fields.len() != names.len() {
            return Err(err(
                line,
                "",
                format!(
                    "{} fields, the header has {} columns",
                    fields.len(),
                    names.len()
                ),
            ));
        }
        let row = Row {
            origin,
            line,
            fields: &fields,
            index: &index,
        };
        let object = row.raw("object")?.to_string();
        let g = row.positive_int("g")?;
        let p = row.positive_int("p")?;
        let size = Bytes(row.count("size_bytes")?);
        let gpu = row.optional("gpu_bytes", Row::count)?.map(Bytes);
        let quads = row.optional("quads", Row::count)?;
        let ssim = row.ssim()?;
        let psnr = row.optional("psnr", |r, c| r.number(c, true))?;
        let lpips = row.optional("lpips", |r, c| r.number(c, false))?;
        if let Some(first) = seen.insert((object.clone(), g, p), line) {
            return Err(err(
                line,
                "",
                format!("duplicate sample ({object}, g {g}, p {p}) (also line {first})"),
            ));
        }
        out.push(Sample {
            object,
            g,
            p,
            size,
            gpu,
            quads,
            ssim,
            psnr,
            lpips,
            line,
        });
    }
    if out.is_empty() {
        return Err(err(0, "", "no samples after the header".into()));
    }
    Ok(out)
}

/// One data line being read, for error messages with line and column.
struct Row<'r> {
    origin: &'r str,
    line: usize,
    fields: &'r [String],
    index: &'r HashMap<String, usize>,
}

impl Row<'_> {
    fn fail(&self, column: &str, message: String) -> SamplesError {
        SamplesError {
            origin: self.origin.to_string(),
            line: self.line,
            column: column.to_string(),
            message,
        }
    }

    fn get(&self, column: &str) -> Option<&str> {
        let i = *self.index.get(column)?;
        self.fields.get(i).map(|s| s.trim())
    }

    fn raw(&self, column: &str) -> Result<&str, SamplesError> {
        match self.get(column) {
            Some(s) if !s.is_empty() => Ok(s),
            _ => Err(self.fail(column, "empty".into())),
        }
    }

    fn optional<T>(
        &self,
        column: &str,
        f: impl Fn(&Self, &str) -> Result<T, SamplesError>,
    ) -> Result<Option<T>, SamplesError> {
        match self.get(column) {
            None | Some("") => Ok(None),
            Some(_) => f(self, column).map(Some),
        }
    }

    fn positive_int(&self, column: &str) -> Result<u32, SamplesError> {
        let s = self.raw(column)?;
        match s.parse::<u32>() {
            Ok(v) if v > 0 => Ok(v),
            _ => Err(self.fail(column, format!("expected a positive integer, got {s:?}"))),
        }
    }

    fn count(&self, column: &str) -> Result<u64, SamplesError> {
        let s = self.raw(column)?;
        s.parse::<u64>().map_err(|_| {
            self.fail(
                column,
                format!("expected a non-negative whole number, got {s:?}"),
            )
        })
    }

    fn number(&self, column: &str, allow_inf: bool) -> Result<f64, SamplesError> {
        let s = self.raw(column)?;
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() || (allow_inf && v == f64::INFINITY) => Ok(v),
            _ => Err(self.fail(column, format!("expected a number, got {s:?}"))),
        }
    }

    fn ssim(&self) -> Result<f64, SamplesError> {
        let v = self.number("ssim", false)?;
        if !(-1.0..=1.0).contains(&v) {
            return Err(self.fail("ssim", format!("{v} is outside [-1, 1]")));
        }
        Ok(v)
    }
}

/// Splits one CSV line: commas separate fields; a field may be
/// double-quoted (`""` is a literal quote inside quotes).
fn split(line: &str) -> Result<Vec<String>, String> {
    let mut fields = Vec::new();
    let mut cur = String::new();
    let mut chars = line.chars().peekable();
    let mut quoted = false;
    let mut was_quoted = false;
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                cur.push('"');
                chars.next();
            }
            ('"', true) => quoted = false,
            ('"', false) if cur.trim().is_empty() && !was_quoted => {
                cur.clear();
                quoted = true;
                was_quoted = true;
            }
            (',', false) => {
                fields.push(std::mem::take(&mut cur));
                was_quoted = false;
            }
            _ => cur.push(c),
        }
    }
    if quoted {
        return Err("unterminated double quote".into());
    }
    fields.push(cur);
    Ok(fields)
}

/// Writes samples as CSV (all [`COLUMNS`]; missing optional values empty)
/// through a temporary file, so an existing file is never left truncated.
pub fn write(path: &Path, samples: &[Sample]) -> std::io::Result<()> {
    let mut text = COLUMNS.join(",");
    text.push('\n');
    let opt = |v: Option<String>| v.unwrap_or_default();
    for s in samples {
        let name = if s.object.contains([',', '"']) {
            format!("\"{}\"", s.object.replace('"', "\"\""))
        } else {
            s.object.clone()
        };
        text.push_str(&format!(
            "{name},{},{},{},{},{},{},{},{}\n",
            s.g,
            s.p,
            s.size.0,
            opt(s.gpu.map(|b| b.0.to_string())),
            opt(s.quads.map(|q| q.to_string())),
            s.ssim,
            opt(s.psnr.map(|v| v.to_string())),
            opt(s.lpips.map(|v| v.to_string())),
        ));
    }
    crate::fit::write_atomic(path, text.as_bytes())
}

/// Object names in order of first appearance.
pub fn objects(samples: &[Sample]) -> Vec<&str> {
    let mut names: Vec<&str> = Vec::new();
    for s in samples {
        if !names.contains(&s.object.as_str()) {
            names.push(&s.object);
        }
    }
    names
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str = "object,g,p,size_bytes,gpu_bytes,quads,ssim,psnr,lpips";

    fn err(body: &str) -> String {
        parse(&format!("{HEADER}\n{body}"), "sweep.csv")
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn parses_rows_and_optional_columns() {
        let text = format!(
            "# sweep\n{HEADER}\nlego,16,5,1000,2000,30,0.7,inf,\n\n\"a, \"\"b\"\"\",32,9,5000,,,0.8,21.5,0.2\r\n"
        );
        let s = parse(&text, "x.csv").unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(
            (s[0].g, s[0].p, s[0].size, s[0].line),
            (16, 5, Bytes(1000), 3)
        );
        assert_eq!(s[0].gpu, Some(Bytes(2000)));
        assert_eq!(s[0].psnr, Some(f64::INFINITY));
        assert_eq!(s[0].lpips, None);
        assert_eq!(s[1].object, "a, \"b\"");
        assert_eq!((s[1].gpu, s[1].quads, s[1].lpips), (None, None, Some(0.2)));
        assert_eq!(objects(&s), vec!["lego", "a, \"b\""]);
        // Columns in another order, extra columns, optional ones absent.
        let s = parse(
            "ssim,p,extra,g,object,size_bytes\n0.5,3,x,8,o,10\n",
            "y.csv",
        )
        .unwrap();
        assert_eq!((s[0].g, s[0].p, s[0].ssim, s[0].gpu), (8, 3, 0.5, None));
    }

    #[test]
    fn errors_name_file_line_and_column() {
        assert_eq!(
            err("lego,16,5,1000,,,abc,,"),
            "sweep.csv:2: ssim: expected a number, got \"abc\""
        );
        assert_eq!(
            err("lego,16,5,1000,,,0.5,,\nlego,0,5,1000,,,0.5,,"),
            "sweep.csv:3: g: expected a positive integer, got \"0\""
        );
        assert_eq!(
            err("lego,16,5,-3,,,0.5,,"),
            "sweep.csv:2: size_bytes: expected a non-negative whole number, got \"-3\""
        );
        assert_eq!(
            err("lego,16,5,3,,,1.5,,"),
            "sweep.csv:2: ssim: 1.5 is outside [-1, 1]"
        );
        assert_eq!(
            err("lego,16,5,3,,,0.5"),
            "sweep.csv:2: 7 fields, the header has 9 columns"
        );
        assert_eq!(err(",16,5,3,,,0.5,,"), "sweep.csv:2: object: empty");
        assert_eq!(
            err("lego,16,5,3,,,0.5,,\nlego,16,5,4,,,0.6,,"),
            "sweep.csv:3: duplicate sample (lego, g 16, p 5) (also line 2)"
        );
        assert_eq!(
            err("\"lego,16,5,3,,,0.5,,"),
            "sweep.csv:2: unterminated double quote"
        );
        assert_eq!(err(""), "sweep.csv: no samples after the header");
        assert_eq!(
            parse("", "e.csv").unwrap_err().to_string(),
            "e.csv: empty file: expected a header line"
        );
        assert!(parse("object,g,p,ssim\n", "h.csv")
            .unwrap_err()
            .to_string()
            .starts_with("h.csv:1: missing column \"size_bytes\""));
    }

    #[test]
    fn write_then_read_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.csv");
        let mut s = parse(
            &format!(
                "{HEADER}\nlego,16,5,1000,2000,30,0.7,inf,\n\"x,y\",32,9,5000,,,0.8,21.5,0.2\n"
            ),
            "x.csv",
        )
        .unwrap();
        write(&path, &s).unwrap();
        let back = read(&path).unwrap();
        s[0].line = 2;
        s[1].line = 3;
        assert_eq!(back, s);
    }
}
