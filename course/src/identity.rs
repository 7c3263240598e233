//! A student copy's identity, so that copies can share one build of the dependencies.
//!
//! Cargo names a crate's artifacts and fingerprints by a hash of its package id, and for the
//! root package of a workspace that id holds the name, the version and the path relative to
//! the workspace: the same for every copy of the crate. Two copies built in one directory
//! would overwrite each other's artifacts, and Cargo, which judges a local crate fresh by
//! modification times, could then grade one student's build for another's. `assignment make`
//! therefore writes a version with build metadata, `0.1.0+copy.ID`, into the copy's
//! `Cargo.toml` and `Cargo.lock`: the crate keeps its name (`use pathspace::...`, the binary
//! `pathspace`), its hash changes, and the dependencies, whose hashes do not depend on the
//! crate that uses them, are compiled once for every copy (`assignment check --build-dir`).

use std::hash::{BuildHasher, Hasher};
use std::path::Path;

use super::{CourseError, Tree};

/// What precedes a copy's id in its version.
pub const MARK: &str = "+copy.";

/// A new id for the copy written to `out`: its path, the time and the process, hashed to 16
/// hex digits. Ids need only differ between copies, not repeat.
pub fn fresh(out: &Path) -> String {
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write(out.to_string_lossy().as_bytes());
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default();
    h.write_u128(now.as_nanos());
    h.write_u32(std::process::id());
    format!("{:016x}", h.finish())
}

/// The id of the crate whose `Cargo.toml` is `text`, when it is a copy `assignment make`
/// wrote.
pub fn of(cargo_toml: &str) -> Option<String> {
    let (_, v) = package_field(cargo_toml, "version")?;
    let id = v.split_once(MARK)?.1;
    (!id.is_empty() && id.chars().all(|c| c.is_ascii_alphanumeric())).then(|| id.to_string())
}

/// Writes `id` into the copy's `Cargo.toml` and, for the crate's own entry, its `Cargo.lock`;
/// likewise into every workspace member's, so that no crate of the copy shares its artifacts'
/// names with the original's (a member's path within its workspace is the same in both).
pub fn stamp(tree: &mut Tree, id: &str) -> Result<(), CourseError> {
    let toml = tree
        .get("Cargo.toml")
        .and_then(|b| std::str::from_utf8(b).ok())
        .ok_or_else(|| CourseError::Identity("the copy has no UTF-8 Cargo.toml".into()))?
        .to_string();
    stamp_package(tree, "Cargo.toml", id)?;
    for m in super::workspace_members(&toml) {
        let manifest = format!("{m}/Cargo.toml");
        if tree.contains_key(&manifest) {
            stamp_package(tree, &manifest, id)?;
        }
    }
    Ok(())
}

/// Stamps the package of the manifest `manifest` (and its entry in the copy's `Cargo.lock`).
fn stamp_package(tree: &mut Tree, manifest: &str, id: &str) -> Result<(), CourseError> {
    let unstampable = |why: &str| CourseError::Identity(format!("{manifest}: {why}"));
    let toml = tree
        .get(manifest)
        .and_then(|b| std::str::from_utf8(b).ok())
        .ok_or_else(|| unstampable("not UTF-8"))?
        .to_string();
    let (_, name) =
        package_field(&toml, "name").ok_or_else(|| unstampable("no `name` in [package]"))?;
    let (line, version) =
        package_field(&toml, "version").ok_or_else(|| unstampable("no `version` in [package]"))?;
    let base = version
        .split_once(MARK)
        .map_or(version.as_str(), |(b, _)| b);
    let stamped = format!("{base}{MARK}{id}");
    let new_toml = replace_line(&toml, line, &format!("version = \"{stamped}\""));
    tree.insert(manifest.into(), new_toml.into_bytes());
    if let Some(lock) = tree.get("Cargo.lock") {
        let lock = String::from_utf8_lossy(lock).to_string();
        let lines: Vec<&str> = lock.lines().collect();
        let at = lines
            .windows(2)
            .position(|w| w[0] == format!("name = \"{name}\"") && w[1].starts_with("version = "))
            .ok_or_else(|| unstampable("Cargo.lock has no entry for the crate"))?;
        let new_lock = replace_line(&lock, at + 1, &format!("version = \"{stamped}\""));
        tree.insert("Cargo.lock".into(), new_lock.into_bytes());
    }
    Ok(())
}

/// The `name` of the `[package]` of a `Cargo.toml`.
pub fn package_name(cargo_toml: &str) -> Option<String> {
    package_field(cargo_toml, "name").map(|(_, n)| n)
}

/// The 0-based line and the string value of `key = "..."` in the `[package]` table.
fn package_field(toml: &str, key: &str) -> Option<(usize, String)> {
    let mut in_package = false;
    for (i, l) in toml.lines().enumerate() {
        let t = l.trim();
        if t.starts_with('[') {
            in_package = t == "[package]";
        } else if in_package {
            let Some((k, v)) = t.split_once('=') else {
                continue;
            };
            if k.trim() == key {
                let v = v.trim().strip_prefix('"')?.strip_suffix('"')?;
                return Some((i, v.to_string()));
            }
        }
    }
    None
}

fn replace_line(text: &str, at: usize, with: &str) -> String {
    let mut out: Vec<&str> = text.lines().collect();
    out[at] = with;
    let mut s = out.join("\n");
    if text.ends_with('\n') {
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const TOML: &str = "[package]\nname = \"pathspace\"\nversion = \"0.1.0\"\n\n[dependencies]\nglam = { version = \"0.30\" }\n";
    const LOCK: &str = "[[package]]\nname = \"glam\"\nversion = \"0.30.0\"\n\n[[package]]\nname = \"pathspace\"\nversion = \"0.1.0\"\n";

    fn tree() -> Tree {
        [("Cargo.toml", TOML), ("Cargo.lock", LOCK)]
            .into_iter()
            .map(|(p, t)| (p.to_string(), t.as_bytes().to_vec()))
            .collect()
    }

    #[test]
    fn stamping_changes_the_crates_version_only_and_can_be_read_back() {
        let mut t = tree();
        stamp(&mut t, "0123abcd").unwrap();
        let toml = String::from_utf8(t["Cargo.toml"].clone()).unwrap();
        let lock = String::from_utf8(t["Cargo.lock"].clone()).unwrap();
        assert_eq!(toml, TOML.replace("\"0.1.0\"", "\"0.1.0+copy.0123abcd\""));
        assert_eq!(lock, LOCK.replace("\"0.1.0\"", "\"0.1.0+copy.0123abcd\""));
        assert_eq!(of(&toml).as_deref(), Some("0123abcd"));
        assert_eq!(of(TOML), None);
        // a copy of a copy gets the new id, not two
        stamp(&mut t, "ff").unwrap();
        let toml = String::from_utf8(t["Cargo.toml"].clone()).unwrap();
        assert!(toml.contains("version = \"0.1.0+copy.ff\"\n"), "{toml}");
    }

    #[test]
    fn every_workspace_member_is_stamped_too() {
        let root = "[package]\nname = \"pathspace\"\nversion = \"0.1.0\"\n\n[workspace]\nmembers = [\"course\"]\n";
        let member = "[package]\nname = \"pathspace-course\"\nversion = \"0.2.0\"\n";
        let lock =
            format!("{LOCK}\n[[package]]\nname = \"pathspace-course\"\nversion = \"0.2.0\"\n");
        let mut t: Tree = [
            ("Cargo.toml", root.to_string()),
            ("course/Cargo.toml", member.to_string()),
            ("Cargo.lock", lock),
        ]
        .into_iter()
        .map(|(p, t)| (p.to_string(), t.into_bytes()))
        .collect();
        stamp(&mut t, "ab12").unwrap();
        let member = String::from_utf8(t["course/Cargo.toml"].clone()).unwrap();
        let lock = String::from_utf8(t["Cargo.lock"].clone()).unwrap();
        assert!(member.contains("version = \"0.2.0+copy.ab12\""), "{member}");
        assert!(
            lock.contains("name = \"pathspace-course\"\nversion = \"0.2.0+copy.ab12\""),
            "{lock}"
        );
        assert!(
            lock.contains("name = \"pathspace\"\nversion = \"0.1.0+copy.ab12\""),
            "{lock}"
        );
    }

    #[test]
    fn ids_differ_between_copies() {
        assert_ne!(fresh(Path::new("a")), fresh(Path::new("a")));
        assert_eq!(fresh(Path::new("a")).len(), 16);
    }
}
