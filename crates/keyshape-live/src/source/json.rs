//! A JSON line of standard input: `{"t": …, "points": [[x, y], …]}`.

/// The points of one JSON line `{"t": …, "points": [[x, y], …]}` (extra values per point,
/// such as z, are read past).
pub(super) fn json_points(line: &str) -> std::result::Result<(Option<f64>, Vec<f64>), String> {
    let v: serde_json::Value = serde_json::from_str(line).map_err(|e| format!("not JSON: {e}"))?;
    let t = v.get("t").and_then(serde_json::Value::as_f64);
    let pts = v
        .get("points")
        .and_then(serde_json::Value::as_array)
        .ok_or("no \"points\" array")?;
    let mut out = Vec::with_capacity(2 * pts.len());
    for (i, p) in pts.iter().enumerate() {
        let xy = p
            .as_array()
            .filter(|a| a.len() >= 2)
            .ok_or_else(|| format!("point {i} is not [x, y]"))?;
        for c in &xy[..2] {
            let c = c
                .as_f64()
                .filter(|c| c.is_finite())
                .ok_or_else(|| format!("point {i}: not a finite number"))?;
            out.push(c);
        }
    }
    Ok((t, out))
}
