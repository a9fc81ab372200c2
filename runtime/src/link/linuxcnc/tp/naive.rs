//! canon's naive-CAM detector (emccanon.cc `see_segment`, `linkable`, `flush_segments`), the
//! part that joins straight feeds: whether the next line the model reads joins the chain
//! read so far ([`super::read::Reader`] keeps the chain and ends it where canon flushes it).

/// Whether canon's naive-CAM detector joins a straight feed to `to` onto the chain that
/// started at `from` and has reached `points` (emccanon.cc `linkable`): at most 100 points
/// chained, not back at the chain's start, and every chained point within `tol` (`G64 Q`,
/// else P) of the line from the start to `to`. Joined, the chain runs as that one line, at
/// the feed, with the last line's number: a run of short, nearly collinear lines (a text
/// stroke continuing its lead-in) has no junctions to slow down at.
pub(super) fn joins(from: &[f64], points: &[Vec<f64>], to: &[f64], tol: f64) -> bool {
    let m: Vec<f64> = to.iter().zip(from).map(|(t, f)| t - f).collect();
    let mm: f64 = m.iter().map(|v| v * v).sum();
    if points.len() > 100 || mm <= 0.0 {
        return false;
    }
    points.iter().all(|p| {
        let d: Vec<f64> = p.iter().zip(from).map(|(p, f)| p - f).collect();
        let t = (m.iter().zip(&d).map(|(a, b)| a * b).sum::<f64>() / mm).clamp(0.0, 1.0);
        let off: f64 = d.iter().zip(&m).map(|(d, m)| (d - t * m).powi(2)).sum();
        off <= tol * tol
    })
}
