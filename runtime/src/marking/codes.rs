//! 2D codes: QR (through the `qrcode` crate) and Data Matrix ECC 200 (through `datamatrix`),
//! as a grid of dark and light modules placed in mm. A symbol is marked either by filling its
//! dark modules (one rectangle per run of dark modules in a row, for `scan raster`) or by one
//! pulse at each dark module's centre (for `scan dots`).

use crate::geometry::{Profile, V2};

/// Which symbology.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Symbology {
    Qr,
    DataMatrix,
}

impl Symbology {
    /// The quiet zone the standard asks for, in modules: 4 for QR (ISO/IEC 18004), 1 for Data
    /// Matrix (ISO/IEC 16022).
    pub fn default_quiet(self) -> u32 {
        match self {
            Symbology::Qr => 4,
            Symbology::DataMatrix => 1,
        }
    }
}

/// A symbol's modules, row 0 at the top as printed: `dark[row * size.0 + col]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Modules {
    /// Columns and rows.
    pub size: (usize, usize),
    pub dark: Vec<bool>,
}

/// The symbol of `text`, or why it cannot be made (too long for the largest symbol).
pub fn encode(sym: Symbology, text: &str) -> Result<Modules, String> {
    match sym {
        Symbology::Qr => {
            // Level M: 15 % of the symbol can be lost to a bad mark, the usual choice for
            // direct part marking where contrast is not perfect.
            let code = qrcode::QrCode::with_error_correction_level(text, qrcode::EcLevel::M)
                .map_err(|e| format!("{e}"))?;
            let w = code.width();
            Ok(Modules {
                size: (w, w),
                dark: code
                    .to_colors()
                    .into_iter()
                    .map(|c| c == qrcode::Color::Dark)
                    .collect(),
            })
        }
        Symbology::DataMatrix => {
            let code = datamatrix::DataMatrix::encode_str(
                text,
                datamatrix::SymbolList::default().enforce_square(),
            )
            .map_err(|e| format!("{e:?}"))?;
            let bm = code.bitmap();
            Ok(Modules {
                size: (bm.width(), bm.height()),
                dark: bm.bits().to_vec(),
            })
        }
    }
}

/// Where the modules go: the lower-left corner of the quiet zone, the module size and the
/// quiet zone's width in modules.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    pub at: V2,
    pub module: f64,
    pub quiet: u32,
}

impl Modules {
    fn is_dark(&self, col: usize, row: usize) -> bool {
        self.dark[row * self.size.0 + col]
    }

    /// The lower-left corner of module (col, row) in mm: rows count down from the top, y up.
    fn corner(&self, col: usize, row: usize, p: &Placement) -> V2 {
        let q = f64::from(p.quiet);
        p.at + V2::new(
            (q + col as f64) * p.module,
            (q + (self.size.1 - 1 - row) as f64) * p.module,
        )
    }

    /// The symbol's side with its quiet zone, mm.
    pub fn extent(&self, p: &Placement) -> (f64, f64) {
        let q = 2.0 * f64::from(p.quiet);
        (
            (self.size.0 as f64 + q) * p.module,
            (self.size.1 as f64 + q) * p.module,
        )
    }

    /// One closed rectangle per run of dark modules in a row, counter-clockwise. Runs of one
    /// row touch those of the next only along their edges, so the even-odd fill of the list is
    /// exactly the dark area.
    pub fn runs(&self, p: &Placement) -> Vec<Profile> {
        let mut out = Vec::new();
        for row in 0..self.size.1 {
            let mut col = 0;
            while col < self.size.0 {
                if !self.is_dark(col, row) {
                    col += 1;
                    continue;
                }
                let start = col;
                while col < self.size.0 && self.is_dark(col, row) {
                    col += 1;
                }
                let a = self.corner(start, row, p);
                let w = (col - start) as f64 * p.module;
                let pts = [
                    a,
                    a + V2::new(w, 0.0),
                    a + V2::new(w, p.module),
                    a + V2::new(0.0, p.module),
                ];
                out.push(Profile::polyline(&pts, true).expect("a rectangle of positive size"));
            }
        }
        out
    }

    /// The centre of every dark module, row by row from the top.
    pub fn centres(&self, p: &Placement) -> Vec<V2> {
        let half = V2::new(p.module, p.module) / 2.0;
        (0..self.size.1)
            .flat_map(|row| (0..self.size.0).map(move |col| (col, row)))
            .filter(|&(c, r)| self.is_dark(c, r))
            .map(|(c, r)| self.corner(c, r, p) + half)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_data_matrix_decodes_back_from_its_own_modules() {
        let m = encode(Symbology::DataMatrix, "LOT 42").unwrap();
        assert_eq!(m.size.0, m.size.1);
        let text = datamatrix::DataMatrix::decode(&m.dark, m.size.0).unwrap();
        assert_eq!(text, b"LOT 42");
    }

    #[test]
    fn runs_cover_exactly_the_dark_modules_and_centres_sit_in_them() {
        let m = encode(Symbology::Qr, "lase").unwrap();
        let p = Placement {
            at: V2::new(10.0, 20.0),
            module: 0.5,
            quiet: 4,
        };
        let dark = m.dark.iter().filter(|d| **d).count();
        let area: f64 = m.runs(&p).iter().map(|r| r.signed_area()).sum();
        assert!((area - dark as f64 * 0.25).abs() < 1e-9, "{area}");
        let c = m.centres(&p);
        assert_eq!(c.len(), dark);
        // The top-left finder's corner module is dark: its centre is half a module inside
        // the quiet zone from the symbol's top-left.
        let top = 20.0 + (4.0 + m.size.1 as f64) * 0.5;
        assert!((c[0] - V2::new(10.0 + 2.0 + 0.25, top - 0.25)).norm() < 1e-12);
        assert_eq!(m.extent(&p).0, (m.size.0 as f64 + 8.0) * 0.5);
    }

    #[test]
    fn too_much_text_is_refused_not_truncated() {
        let long = "x".repeat(5000);
        assert!(encode(Symbology::Qr, &long).is_err());
        assert!(encode(Symbology::DataMatrix, &long).is_err());
    }
}
