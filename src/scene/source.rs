//! Reading a scene: the bytes of a file (at most [`MAX_SCENE_BYTES`] of UTF-8), handed to the
//! reader of its format. A `.xml` file is Mitsuba 3 XML, translated by `scene::mitsuba`; any
//! other is pathspace's TOML, kept as it is. Both readers produce the same [`SceneSource`] (the
//! scene file's text, with the original lines of a translated one), which `scene::file` defines
//! below both: the dispatch lives here, above them, so neither reader knows the other.
//! Book: "Scenes and geometry" and "Importing scenes".

use std::io::Read;
use std::path::{Path, PathBuf};

use super::file::{self, SceneError, SceneSource, FILE_KEY, MAX_SCENE_BYTES};
use super::mitsuba;

/// The formats a scene file can be in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// pathspace's scene file (`scene::file`).
    Toml,
    /// Mitsuba 3 scene XML (`scene::mitsuba`).
    MitsubaXml,
}

impl Format {
    /// The format of the file at `path`, told by its extension (`.xml`, in any case, is
    /// Mitsuba's).
    pub fn of(path: &Path) -> Format {
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("xml"))
        {
            Format::MitsubaXml
        } else {
            Format::Toml
        }
    }
}

impl SceneSource {
    /// Reads a file of at most [`MAX_SCENE_BYTES`] bytes of UTF-8 in its [`Format`].
    pub fn read(path: &Path) -> Result<Self, SceneError> {
        let name = path.display().to_string();
        let text = read_text(path, &name)?;
        let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        match Format::of(path) {
            Format::MitsubaXml => mitsuba::import(&name, &text, base_dir),
            Format::Toml => Ok(SceneSource::toml(name, text, base_dir)),
        }
    }

    /// A scene file's text as it is, relative paths from `base_dir`.
    fn toml(name: String, text: String, base_dir: PathBuf) -> Self {
        SceneSource {
            name,
            text,
            base_dir,
            origin: None,
            inputs: Default::default(),
        }
    }
}

/// The text of the file at `path` (called `name` in errors): its size checked while it is
/// read, its bytes decoded as UTF-8.
fn read_text(path: &Path, name: &str) -> Result<String, SceneError> {
    let mut bytes = Vec::new();
    // one byte more than the limit tells a file at the limit from a longer one
    std::fs::File::open(path)
        .and_then(|f| f.take(MAX_SCENE_BYTES as u64 + 1).read_to_end(&mut bytes))
        .map_err(|e| SceneError {
            file: name.to_string(),
            line: None,
            key: FILE_KEY.into(),
            message: format!("cannot read the scene file: {e}"),
        })?;
    file::check_size(name, bytes.len())?;
    file::decode(bytes, name)
}
