//! One error type for everything that reads user input (scene files, meshes).
//!
//! Every error names the file, and the line where there is one, so a user can go
//! straight to the offending spot: `scene.obj:1234: face index 99 out of range`.

use std::fmt;
use std::path::{Path, PathBuf};

/// An error while loading a scene or a mesh.
#[derive(Debug)]
pub struct LoadError {
    /// The file the problem is in.
    pub path: PathBuf,
    /// 1-based line number, for text formats, where known.
    pub line: Option<usize>,
    /// What is wrong, in words.
    pub message: String,
}

impl LoadError {
    /// An error about a whole file (no line).
    pub fn new(path: impl AsRef<Path>, message: impl Into<String>) -> Self {
        Self { path: path.as_ref().to_path_buf(), line: None, message: message.into() }
    }

    /// An error at a 1-based line of a text file.
    pub fn at_line(path: impl AsRef<Path>, line: usize, message: impl Into<String>) -> Self {
        Self { path: path.as_ref().to_path_buf(), line: Some(line), message: message.into() }
    }
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}: {}", self.path.display(), line, self.message),
            None => write!(f, "{}: {}", self.path.display(), self.message),
        }
    }
}

impl std::error::Error for LoadError {}
