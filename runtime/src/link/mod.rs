//! Controller links: where NC lines go when lase drives a machine live.
//!
//! Architecture invariant: this is the only code that knows a controller protocol. A
//! [`Link`] takes one NC line at a time and answers whether the controller accepted it. The
//! in-process [`sim::SimController`] is a real implementation that executes what it receives
//! (modal state, positions, laser), so a job can be run end to end with no machine.

pub mod sim;

/// What a controller said about a line.
#[derive(Debug, Clone, PartialEq)]
pub enum Reply {
    Ok,
    /// The controller refused the line (GRBL's `error:N`), with its reason.
    Error {
        code: u32,
        message: String,
    },
}

/// Transport-level failure.
#[derive(Debug, Clone, thiserror::Error, miette::Diagnostic, PartialEq)]
pub enum LinkError {
    #[error("unsupported controller link `{url}`")]
    #[diagnostic(code(lase::link::unsupported))]
    Unsupported {
        url: String,
        #[help]
        help: Option<String>,
    },
}

pub trait Link {
    /// Sends one line (without newline) and waits for the controller's reply.
    fn send(&mut self, line: &str) -> Result<Reply, LinkError>;
    /// A one-line description of the controller's state.
    fn status(&self) -> String;
}

/// Opens a link from a URL. Only the built-in simulator (`sim`) is available in this version.
pub fn open(
    url: Option<&str>,
    machine: &crate::machine::Machine,
) -> Result<Box<dyn Link>, LinkError> {
    match url {
        None | Some("sim") | Some("sim://") => Ok(Box::new(sim::SimController::new(machine))),
        Some(other) => Err(LinkError::Unsupported {
            url: other.to_string(),
            help: Some(
                "this version streams to the built-in simulator only (`--link sim`); write the \
                 program with `lase emit` and load it on the controller"
                    .into(),
            ),
        }),
    }
}
