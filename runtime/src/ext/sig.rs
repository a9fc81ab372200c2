//! Extension signatures: what a Rhai function declares it takes and returns, in recipe types.
//!
//! Rhai parameters have no types, so an exported function says in a doc comment line:
//!
//! ```rhai
//! /// The lift of my law at cam angle `theta`.
//! /// lase: (theta: angle, rise: length) -> length
//! fn my_lift(theta, rise) { ... }
//! ```
//!
//! Types are the recipe's annotation names (`number`, `length`, `angle`, `speed`, `power`,
//! `point`, `profile`, `bool`, `string`, `list`, ...) and `[T]` for a list of `T`
//! (`[point]` for a spot pattern). Only functions with such a line are callable from a
//! recipe; the others are the module's helpers.

use lase_lang::{ExtSig, Ty};

/// The signature of one Rhai function from its doc comments, if it declares one.
pub(crate) fn parse(
    name: &str,
    params: &[&str],
    comments: &[&str],
) -> Option<Result<ExtSig, String>> {
    let mut doc = Vec::new();
    let mut sig = None;
    for c in comments {
        for line in c.lines() {
            let line = line
                .trim()
                .trim_start_matches("/**")
                .trim_end_matches("*/")
                .trim_start_matches("///")
                .trim_start_matches('*');
            let line = line.strip_prefix(' ').unwrap_or(line);
            match line.trim_start().strip_prefix("lase:") {
                Some(s) => sig = Some(s.trim().to_string()),
                None => doc.push(line.to_string()),
            }
        }
    }
    let sig = sig?;
    Some(parse_sig(name, params, &sig).map(|(params, ret)| ExtSig {
        name: name.to_string(),
        params,
        ret,
        doc: doc.join("\n").trim().to_string(),
    }))
}

type Parsed = (Vec<(String, Ty)>, Ty);

fn parse_sig(name: &str, rhai_params: &[&str], sig: &str) -> Result<Parsed, String> {
    let (args, ret) = match sig.rsplit_once("->") {
        Some((a, r)) => (a.trim(), Some(r.trim())),
        None => (sig, None),
    };
    let inner = args
        .strip_prefix('(')
        .and_then(|a| a.strip_suffix(')'))
        .ok_or_else(|| format!("`{sig}` should read `(a: length, ...) -> type`"))?;
    let mut params = Vec::new();
    for p in inner.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (n, t) = p
            .split_once(':')
            .ok_or_else(|| format!("parameter `{p}` needs a type: `{p}: length`"))?;
        params.push((n.trim().to_string(), ty(t.trim())?));
    }
    let declared: Vec<&str> = params.iter().map(|(n, _)| n.as_str()).collect();
    if declared != rhai_params {
        return Err(format!(
            "the signature names ({}) differ from the parameters of `fn {name}({})`",
            declared.join(", "),
            rhai_params.join(", ")
        ));
    }
    let ret = match ret {
        Some(r) => ty(r)?,
        None => Ty::Nothing,
    };
    Ok((params, ret))
}

/// A type name, or `[T]` for a list.
pub(crate) fn ty(t: &str) -> Result<Ty, String> {
    if let Some(inner) = t.strip_prefix('[').and_then(|t| t.strip_suffix(']')) {
        return Ok(Ty::List(Box::new(ty(inner.trim())?)));
    }
    if t == "()" {
        return Ok(Ty::Nothing);
    }
    Ty::from_name(t).ok_or_else(|| {
        format!(
            "`{t}` is not a type; types are {} and [T] for a list",
            lase_lang::schema::TYPE_NAMES.join(", ")
        )
    })
}

/// How a signature reads in docs and help: `(theta: angle, rise: length) -> length`.
pub fn describe(sig: &ExtSig) -> String {
    fn name(t: &Ty) -> String {
        match t {
            Ty::Num(d) if d.is_none() => "number".into(),
            Ty::Num(d) => d.name().replace(' ', "_"),
            Ty::List(e) if **e == Ty::Unknown => "list".into(),
            Ty::List(e) => format!("[{}]", name(e)),
            Ty::Bool => "bool".into(),
            Ty::Str => "string".into(),
            Ty::Point => "point".into(),
            Ty::Profile => "profile".into(),
            Ty::Nothing => "()".into(),
            Ty::Zero | Ty::Unknown => "any".into(),
        }
    }
    let params: Vec<String> = sig
        .params
        .iter()
        .map(|(n, t)| format!("{n}: {}", name(t)))
        .collect();
    format!("{}({}) -> {}", sig.name, params.join(", "), name(&sig.ret))
}

#[cfg(test)]
mod tests {
    use super::*;
    use lase_lang::units::Dim;

    #[test]
    fn signatures_parse_from_doc_comments() {
        let s = parse(
            "lift",
            &["theta", "h"],
            &["/// Lift.\n/// lase: (theta: angle, h: length) -> length"],
        )
        .unwrap()
        .unwrap();
        assert_eq!(s.params[0].1, Ty::Num(Dim::ANGLE));
        assert_eq!(s.ret, Ty::Num(Dim::LENGTH));
        assert_eq!(s.doc, "Lift.");
        assert_eq!(describe(&s), "lift(theta: angle, h: length) -> length");
        let s = parse("g", &[], &["/// lase: () -> [point]"])
            .unwrap()
            .unwrap();
        assert_eq!(s.ret, Ty::List(Box::new(Ty::Point)));
        assert!(parse("h", &[], &["/// helper"]).is_none());
        let e = parse("k", &["a"], &["/// lase: (b: length) -> length"])
            .unwrap()
            .unwrap_err();
        assert!(e.contains("differ"), "{e}");
        let e = parse("k", &["a"], &["/// lase: (a: lenght) -> length"])
            .unwrap()
            .unwrap_err();
        assert!(e.contains("not a type"), "{e}");
    }
}
