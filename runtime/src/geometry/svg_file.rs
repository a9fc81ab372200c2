//! SVG documents for `profile svg("part.svg")`: the `d` attributes of their `<path>`
//! elements, with their ids, in document order. The path data itself is read by
//! [`super::import::svg_path_profiles`], as for path data written in the recipe.
//!
//! lase reads path coordinates as mm. A document whose user unit is not 1 mm (its `width` in
//! a physical unit against its `viewBox`) or whose paths sit under a `transform` would come in
//! at the wrong size or place, so both are refused with what to change, rather than guessed.

use super::import::ImportError;

/// One `<path>` of a document.
#[derive(Debug, Clone, PartialEq)]
pub struct SvgPath {
    pub id: Option<String>,
    pub d: String,
}

/// The `<path>` elements of an SVG document, in document order.
pub fn svg_document_paths(text: &str) -> Result<Vec<SvgPath>, ImportError> {
    let doc = roxmltree::Document::parse(text)
        .map_err(|e| ImportError::new(format!("not an SVG document: {e}")))?;
    let root = doc.root_element();
    if root.tag_name().name() != "svg" {
        return Err(ImportError::new(format!(
            "not an SVG document: the root element is <{}>",
            root.tag_name().name()
        )));
    }
    user_unit_is_mm(&root)?;
    let mut out = Vec::new();
    for node in root.descendants().filter(|n| n.has_tag_name("path")) {
        let Some(d) = node.attribute("d") else {
            continue;
        };
        let id = node.attribute("id").map(str::to_string);
        if let Some(t) = node
            .ancestors()
            .find_map(|a| a.attribute("transform").filter(|t| !t.trim().is_empty()))
        {
            return Err(ImportError::new(format!(
                "the path{} is drawn under `transform=\"{t}\"`, which lase does not apply; \
                 apply the transforms to the path data in the drawing program first (e.g. \
                 Inkscape: Path → Object to Path)",
                id.as_deref().map(|i| format!(" `{i}`")).unwrap_or_default()
            )));
        }
        out.push(SvgPath {
            id,
            d: d.to_string(),
        });
    }
    if out.is_empty() {
        return Err(ImportError::new(
            "the SVG document has no <path d=…> element".into(),
        ));
    }
    Ok(out)
}

/// A `width` in mm, cm or in against a `viewBox` of another width scales the user unit away
/// from 1 mm.
fn user_unit_is_mm(root: &roxmltree::Node<'_, '_>) -> Result<(), ImportError> {
    let (Some(w), Some(vb)) = (root.attribute("width"), root.attribute("viewBox")) else {
        return Ok(());
    };
    let w = w.trim();
    let mm = [("mm", 1.0), ("cm", 10.0), ("in", 25.4)]
        .iter()
        .find_map(|(u, k)| Some(w.strip_suffix(u)?.trim().parse::<f64>().ok()? * k));
    let vb_w = vb
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .nth(2)
        .and_then(|s| s.parse::<f64>().ok());
    if let (Some(mm), Some(vb_w)) = (mm, vb_w)
        && vb_w > 0.0
        && ((mm / vb_w) - 1.0).abs() > 1e-6
    {
        return Err(ImportError::new(format!(
            "one user unit of this SVG is {} mm (width {w} over a viewBox {vb_w} wide); lase \
             reads path coordinates as mm: set the document's scale to 1 user unit per mm \
             (Inkscape: Document Properties → Scale 1)",
            lase_lang::units::format_number(mm / vb_w)
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_come_with_their_ids_in_document_order() {
        let doc = r#"<svg xmlns="http://www.w3.org/2000/svg" width="40mm" viewBox="0 0 40 20">
            <g><path id="outline" d="M 0 0 L 40 0 L 40 20 Z"/></g>
            <path d="M 5 5 L 10 5"/></svg>"#;
        let p = svg_document_paths(doc).unwrap();
        assert_eq!(p.len(), 2);
        assert_eq!(p[0].id.as_deref(), Some("outline"));
        assert_eq!(p[1].id, None);
        assert_eq!(p[1].d, "M 5 5 L 10 5");
    }

    #[test]
    fn scaled_user_units_and_transforms_are_refused() {
        let scaled = r#"<svg xmlns="http://www.w3.org/2000/svg" width="80mm" viewBox="0 0 40 20"><path d="M 0 0 L 1 0"/></svg>"#;
        let e = svg_document_paths(scaled).unwrap_err().to_string();
        assert!(e.contains("2 mm"), "{e}");
        let moved = r#"<svg xmlns="http://www.w3.org/2000/svg"><g transform="translate(5,0)"><path id="a" d="M 0 0 L 1 0"/></g></svg>"#;
        let e = svg_document_paths(moved).unwrap_err().to_string();
        assert!(e.contains("transform") && e.contains("`a`"), "{e}");
        assert!(svg_document_paths("<html/>").is_err());
        assert!(svg_document_paths("not xml").is_err());
    }
}
