//! `mlp.json`: the MLP weights (`W[in][out]`) and `obj_num`.

use super::{AssetError, MAX_OBJ_NUM};
use nerflex_core::shader::MlpWeights;
use serde_json::Value;
use std::path::Path;

/// Reads `mlp.json`: weights and `obj_num`.
pub fn read(path: &Path) -> Result<(MlpWeights, usize), AssetError> {
    let text = crate::validate::read_to_string(path).map_err(|cause| AssetError::Io {
        path: path.to_path_buf(),
        cause,
    })?;
    parse(&text).map_err(|msg| AssetError::Json {
        path: path.to_path_buf(),
        msg,
    })
}

fn key<'a>(obj: &'a serde_json::Map<String, Value>, k: &str) -> Result<&'a Value, String> {
    obj.get(k).ok_or_else(|| format!("missing key `{k}`"))
}

fn vector<const N: usize>(v: &Value, name: &str) -> Result<[f32; N], String> {
    let a = v
        .as_array()
        .ok_or_else(|| format!("`{name}` must be an array of {N} numbers"))?;
    if a.len() != N {
        return Err(format!("`{name}` has {} entries, expected {N}", a.len()));
    }
    let mut out = [0f32; N];
    for (i, (o, x)) in out.iter_mut().zip(a).enumerate() {
        let f = x
            .as_f64()
            .ok_or_else(|| format!("`{name}`[{i}] is not a number: {x}"))?;
        *o = f as f32;
        if !o.is_finite() {
            return Err(format!("`{name}`[{i}] = {f} does not fit an f32"));
        }
    }
    Ok(out)
}

fn matrix<const R: usize, const C: usize>(v: &Value, name: &str) -> Result<[[f32; C]; R], String> {
    let a = v
        .as_array()
        .ok_or_else(|| format!("`{name}` must be a {R}×{C} array of arrays"))?;
    if a.len() != R {
        return Err(format!(
            "`{name}` has {} rows, expected a {R}×{C} matrix (W[in][out])",
            a.len()
        ));
    }
    let mut out = [[0f32; C]; R];
    for (r, (o, row)) in out.iter_mut().zip(a).enumerate() {
        *o = vector::<C>(row, &format!("{name}[{r}]"))?;
    }
    Ok(out)
}

/// Parses the JSON text.
pub fn parse(text: &str) -> Result<(MlpWeights, usize), String> {
    let v: Value = serde_json::from_str(text).map_err(|e| format!("invalid JSON: {e}"))?;
    let obj = v.as_object().ok_or("top level must be a JSON object")?;
    let w = MlpWeights {
        w0: matrix(key(obj, "0_weights")?, "0_weights")?,
        b0: vector(key(obj, "0_bias")?, "0_bias")?,
        w1: matrix(key(obj, "1_weights")?, "1_weights")?,
        b1: vector(key(obj, "1_bias")?, "1_bias")?,
        w2: matrix(key(obj, "2_weights")?, "2_weights")?,
        b2: vector(key(obj, "2_bias")?, "2_bias")?,
    };
    let n = key(obj, "obj_num")?;
    let obj_num = n
        .as_u64()
        .filter(|&n| (1..=MAX_OBJ_NUM as u64).contains(&n))
        .ok_or_else(|| format!("`obj_num` = {n} must be an integer in 1..={MAX_OBJ_NUM}"))?;
    Ok((w, obj_num as usize))
}

/// The JSON text, keys in the export's order; each `f32` written as the
/// shortest `f64` decimal that reads back to it (as the export does).
pub fn to_string(w: &MlpWeights, obj_num: usize) -> String {
    #[derive(serde::Serialize)]
    struct Out {
        #[serde(rename = "0_weights")]
        w0: Vec<Vec<f64>>,
        #[serde(rename = "1_weights")]
        w1: Vec<Vec<f64>>,
        #[serde(rename = "2_weights")]
        w2: Vec<Vec<f64>>,
        #[serde(rename = "0_bias")]
        b0: Vec<f64>,
        #[serde(rename = "1_bias")]
        b1: Vec<f64>,
        #[serde(rename = "2_bias")]
        b2: Vec<f64>,
        obj_num: usize,
    }
    let m = |rows: &[[f32; 16]]| -> Vec<Vec<f64>> {
        rows.iter()
            .map(|r| r.iter().map(|&x| x as f64).collect())
            .collect()
    };
    let out = Out {
        w0: m(&w.w0),
        w1: m(&w.w1),
        w2: w
            .w2
            .iter()
            .map(|r| r.iter().map(|&x| x as f64).collect())
            .collect(),
        b0: w.b0.iter().map(|&x| x as f64).collect(),
        b1: w.b1.iter().map(|&x| x as f64).collect(),
        b2: w.b2.iter().map(|&x| x as f64).collect(),
        obj_num,
    };
    // Serialising plain numbers and arrays cannot fail.
    serde_json::to_string(&out).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_errors_name_the_key() {
        let mut w = MlpWeights::ZERO;
        w.w0[10][15] = -0.091_480_1;
        w.b2[2] = 1.0e-7;
        w.w2[15][2] = 3.25;
        let text = to_string(&w, 3);
        assert!(text.starts_with("{\"0_weights\":[["));
        assert_eq!(parse(&text).unwrap(), (w, 3));
        let cases = [
            (
                text.replace("\"1_bias\"", "\"1_biasx\""),
                "missing key `1_bias`",
            ),
            (text.replace("\"obj_num\":3", "\"obj_num\":0"), "obj_num"),
            ("[1]".to_string(), "JSON object"),
            ("{".to_string(), "invalid JSON"),
        ];
        for (t, want) in cases {
            let e = parse(&t).unwrap_err();
            assert!(e.contains(want), "{e}");
        }
        // Wrong matrix shape: drop one row of 0_weights.
        let mut v: Value = serde_json::from_str(&text).unwrap();
        v["0_weights"].as_array_mut().unwrap().pop();
        let e = parse(&v.to_string()).unwrap_err();
        assert!(e.contains("`0_weights` has 10 rows"), "{e}");
        let mut v: Value = serde_json::from_str(&text).unwrap();
        v["2_weights"][4].as_array_mut().unwrap().push(1.into());
        let e = parse(&v.to_string()).unwrap_err();
        assert!(
            e.contains("`2_weights[4]` has 4 entries, expected 3"),
            "{e}"
        );
        let mut v: Value = serde_json::from_str(&text).unwrap();
        v["1_bias"][2] = "x".into();
        let e = parse(&v.to_string()).unwrap_err();
        assert!(e.contains("`1_bias`[2] is not a number"), "{e}");
    }
}
