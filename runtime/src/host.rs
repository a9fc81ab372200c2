//! Where a recipe's other files come from while it is evaluated: machine files, data files
//! (lift tables, DXF drawings) and extension modules. The evaluator and the extension loader
//! ask through [`Host`]; `compile`'s `Files` implement it for the disk and for memory.

/// Where machine files and data files (lift tables, DXF drawings) come from: the standard
/// library, or a path next to the recipe.
pub trait Host {
    /// Reads a machine file given by path, relative to the file `importer`. Returns the
    /// resolved name and the text.
    fn machine_file(&mut self, importer: &str, path: &str) -> Result<(String, String), String>;
    /// Reads a data file (a cam lift table, a DXF drawing) given by path, relative to the file
    /// `importer`. Returns the resolved name and the text.
    fn data_file(&mut self, importer: &str, path: &str) -> Result<(String, String), String> {
        let _ = importer;
        Err(format!("data files are not available here (\"{path}\")"))
    }
    /// Reads a binary data file (an image to engrave, a font) given by path, relative to the
    /// file `importer`, with the same IO limits as text. Returns the resolved name and the bytes.
    fn binary_file(&mut self, importer: &str, path: &str) -> Result<(String, Vec<u8>), String> {
        let _ = importer;
        Err(format!("binary files are not available here (\"{path}\")"))
    }
    /// Reads an extension module (`use "file.rhai"`) or a preset (`use "file.toml"`) given by
    /// path, relative to the file `importer`. Returns the resolved name and the text.
    fn extension_file(&mut self, importer: &str, path: &str) -> Result<(String, String), String> {
        let _ = importer;
        Err(format!(
            "extension files are not available here (\"{path}\")"
        ))
    }
}

/// A host with no file system: stock machines only.
#[derive(Debug, Default)]
pub struct StdlibOnly;

impl Host for StdlibOnly {
    fn machine_file(&mut self, _importer: &str, path: &str) -> Result<(String, String), String> {
        Err(format!("machine files are not available here (\"{path}\")"))
    }
}
