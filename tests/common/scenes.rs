//! Small scenes several test files build on.

/// A camera, a white material and a fog, for the error tests: a test appends the part it
/// breaks, whose line `k` is line `BASE_LINES + k` of the file.
pub const BASE: &str = r#"# base scene for the error tests
[camera]
type = "pinhole"
eye = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
fov_deg = 40.0
resolution = [8, 8]

[materials.white]
type = "lambert"
albedo = 0.5

[media.fog]
type = "homogeneous"
sigma_a = 0.1
sigma_s = 0.4
"#;

/// The lines of [`BASE`].
pub const BASE_LINES: usize = 16;
