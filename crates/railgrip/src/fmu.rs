//! A model file as an FMI 2.0 Functional Mock-up Unit (Model Exchange and Co-Simulation), for
//! multibody codes, Simulink and test rigs that import FMUs: [`export_fmu`] writes the zip
//! (`modelDescription.xml`, `binaries/<platform>/<id>.<ext>` compiled for this host with the
//! system C compiler, `sources/` for every other platform, `resources/model.json`), from the
//! text the lean model crate writes ([`railgrip_model::fmu`]). The same model file gives the
//! same FMU text (GUID, description, sources) every time; the binary is whatever the compiler
//! makes of it. docs/fmu.md says what a tool sees.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use railgrip_model::fmu::{fmu_text, FmuVariable};
use railgrip_model::{Model, ModelError};

/// How to build an FMU.
#[derive(Debug, Clone, Default)]
pub struct FmuOptions {
    /// Only `sources/` (a source FMU: the importing tool compiles it); no compiler needed.
    pub sources_only: bool,
    /// The C compiler (default: `$CC`, else `cc`).
    pub compiler: Option<String>,
}

/// What [`export_fmu`] wrote.
#[derive(Debug, Clone)]
pub struct Fmu {
    pub path: PathBuf,
    pub model_identifier: String,
    pub guid: String,
    /// `binaries/<platform>` of the compiled library (None for a source FMU).
    pub platform: Option<&'static str>,
    /// The inputs in value-reference order, then the output `mu`.
    pub variables: Vec<FmuVariable>,
    /// Bytes of the FMU.
    pub size: u64,
}

/// Why an FMU could not be written: what, and what to do.
#[derive(Debug, thiserror::Error)]
pub enum FmuError {
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error("{}: {compiler}: no C compiler found ({why}). Hint: install gcc or clang, or name one in CC; or write a source FMU with --fmu-sources-only (the importing tool compiles it)", out.display())]
    NoCompiler {
        out: PathBuf,
        compiler: String,
        why: String,
    },
    #[error("{}: {compiler} could not compile the FMU's sources (kept in {} for a look):\n{stderr}Hint: check the compiler (a C99 compiler for this platform), or write a source FMU with --fmu-sources-only", out.display(), kept.display())]
    Compile {
        out: PathBuf,
        compiler: String,
        kept: PathBuf,
        stderr: String,
    },
    #[error("{}: railgrip builds FMU binaries on x86-64 Linux (binaries/linux64) and x86-64 macOS (binaries/darwin64) only, not on {platform}. Hint: write a source FMU with --fmu-sources-only and let the importing tool compile it", out.display())]
    Platform { out: PathBuf, platform: String },
    #[error("{}: cannot write: {source}. Hint: check that the folder exists and is writable", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: an FMU's file name ends in .fmu. Hint: give e.g. --fmu adhesion.fmu", path.display())]
    Name { path: PathBuf },
}

/// The FMI 2.0 platform folder and library extension of this host, if railgrip builds there
/// (FMI 2.0 names no folder for ARM Linux, and `darwin64` is taken to be x86-64 by tools).
fn host_platform(out: &Path) -> Result<(&'static str, &'static str), FmuError> {
    match (std::env::consts::OS, std::env::consts::ARCH) {
        ("linux", "x86_64") => Ok(("linux64", "so")),
        ("macos", "x86_64") => Ok(("darwin64", "dylib")),
        (os, arch) => Err(FmuError::Platform {
            out: out.to_path_buf(),
            platform: format!("{os} {arch}"),
        }),
    }
}

/// The model identifier for an FMU written to `out`: its file stem as a C identifier (letters,
/// digits and `_`; a leading letter).
pub fn model_identifier(out: &Path) -> String {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut id: String = stem
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if !id.starts_with(|c: char| c.is_ascii_alphabetic()) {
        id.insert_str(0, "fmu_");
    }
    id
}

/// A GUID (`{8-4-4-4-12}` hex digits of a SHA-256) from the model file's bytes, railgrip's
/// version and the FMI wrapper's text: the same model from the same railgrip, the same GUID;
/// another model, or a wrapper that changed, another.
fn guid_of(bytes: &[u8], tool: &str) -> String {
    let mut all = bytes.to_vec();
    all.extend_from_slice(b"\0tool\0");
    all.extend_from_slice(tool.as_bytes());
    all.extend_from_slice(b"\0wrapper\0");
    all.extend_from_slice(railgrip_model::fmu::WRAPPER_TEMPLATE.as_bytes());
    let h = crate::hash::sha256_bytes(&all);
    format!(
        "{{{}-{}-{}-{}-{}}}",
        &h[0..8],
        &h[8..12],
        &h[12..16],
        &h[16..20],
        &h[20..32]
    )
}

/// Writes the model file at `model` as an FMU at `out` (atomically: a failure leaves no file).
/// The model is checked first (a file that fails its checks is refused, naming it); the
/// binary is compiled for this host unless `options.sources_only`.
pub fn export_fmu(model: &Path, out: &Path, options: &FmuOptions) -> Result<Fmu, FmuError> {
    let bytes = std::fs::read(model).map_err(|e| {
        FmuError::Model(ModelError::Read {
            file: model.display().to_string(),
            source: e,
        })
    })?;
    export_fmu_bytes(&bytes, &model.display().to_string(), out, options)
}

/// [`export_fmu`] of a model file's bytes (JSON) named `name` in messages.
pub fn export_fmu_bytes(
    bytes: &[u8],
    name: &str,
    out: &Path,
    options: &FmuOptions,
) -> Result<Fmu, FmuError> {
    if !out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("fmu"))
    {
        return Err(FmuError::Name {
            path: out.to_path_buf(),
        });
    }
    let text = String::from_utf8_lossy(bytes);
    let checked = Model::named(railgrip_model::ModelFile::from_json(&text, name)?, name)?;
    let bytes = bytes.to_vec();
    let id = model_identifier(out);
    let tool = format!("railgrip {}", env!("CARGO_PKG_VERSION"));
    let guid = guid_of(&bytes, &tool);
    let source = Path::new(name)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let text = fmu_text(&checked.file, &id, &guid, &source, &tool);
    let binary = if options.sources_only {
        None
    } else {
        let (platform, ext) = host_platform(out)?;
        let lib = compile(&text.fmu_c, &text.model_h, out, options)?;
        Some((format!("binaries/{platform}/{id}.{ext}"), lib, platform))
    };
    let mut files: Vec<(String, Vec<u8>, u32)> = vec![(
        "modelDescription.xml".into(),
        text.model_description.into_bytes(),
        0o644,
    )];
    if let Some((name, lib, _)) = &binary {
        files.push((name.clone(), lib.clone(), 0o755));
    }
    files.push(("sources/fmu.c".into(), text.fmu_c.into_bytes(), 0o644));
    files.push(("sources/model.h".into(), text.model_h.into_bytes(), 0o644));
    files.push(("resources/model.json".into(), bytes, 0o644));
    let zip = zip_files(&files).map_err(|e| FmuError::Write {
        path: out.to_path_buf(),
        source: std::io::Error::other(e),
    })?;
    railgrip_io::atomic::write_atomically(out, |w| w.write_all(&zip)).map_err(|source| {
        FmuError::Write {
            path: out.to_path_buf(),
            source,
        }
    })?;
    Ok(Fmu {
        path: out.to_path_buf(),
        model_identifier: id,
        guid,
        platform: binary.map(|b| b.2),
        variables: text.variables,
        size: zip.len() as u64,
    })
}

/// The zip of `files` (name, bytes, Unix mode), in order, with a fixed time stamp: the same
/// files give the same bytes.
fn zip_files(files: &[(String, Vec<u8>, u32)]) -> zip::result::ZipResult<Vec<u8>> {
    let mut z = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    for (name, bytes, mode) in files {
        let o = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated)
            .last_modified_time(zip::DateTime::default())
            .unix_permissions(*mode);
        z.start_file(name.as_str(), o)?;
        z.write_all(bytes)?;
    }
    Ok(z.finish()?.into_inner())
}

/// The shared library of `fmu_c` (with `model_h` beside it), compiled by the C compiler into a
/// temporary folder (kept, and named in the error, when compiling fails): C99, -O2, only the
/// FMI functions exported; `fmu_c` itself makes the evaluator use C99 `fma()` and keeps other
/// products from being contracted, so networks give the Rust evaluator's bits. The compiler
/// is `options.compiler`, else `$CC`, else `cc`; it may carry arguments (`ccache gcc`).
fn compile(
    fmu_c: &str,
    model_h: &str,
    out: &Path,
    options: &FmuOptions,
) -> Result<Vec<u8>, FmuError> {
    let cc = options
        .compiler
        .clone()
        .or_else(|| std::env::var("CC").ok().filter(|c| !c.trim().is_empty()))
        .unwrap_or_else(|| "cc".into());
    let mut words = cc.split_whitespace();
    let program = words.next().unwrap_or("cc").to_string();
    let extra: Vec<String> = words.map(str::to_string).collect();
    static SEQ: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "railgrip-fmu-{}-{}",
        std::process::id(),
        SEQ.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    let write = |path: PathBuf, text: &str| {
        std::fs::write(&path, text).map_err(|source| FmuError::Write { path, source })
    };
    let mut keep = false;
    let result = (|| {
        std::fs::create_dir_all(&dir).map_err(|source| FmuError::Write {
            path: dir.clone(),
            source,
        })?;
        write(dir.join("fmu.c"), fmu_c)?;
        write(dir.join("model.h"), model_h)?;
        let lib = dir.join("fmu.so");
        let output = Command::new(&program)
            .args(&extra)
            .args([
                "-std=c99",
                "-O2",
                "-fPIC",
                "-shared",
                "-fvisibility=hidden",
                "-ffp-contract=off",
            ])
            .arg("-o")
            .arg(&lib)
            .arg(dir.join("fmu.c"))
            .arg("-lm")
            .output()
            .map_err(|e| FmuError::NoCompiler {
                out: out.to_path_buf(),
                compiler: cc.clone(),
                why: e.to_string(),
            })?;
        if !output.status.success() {
            keep = true;
            return Err(FmuError::Compile {
                out: out.to_path_buf(),
                compiler: cc.clone(),
                kept: dir.clone(),
                stderr: String::from_utf8_lossy(&output.stderr).into_owned(),
            });
        }
        std::fs::read(&lib).map_err(|source| FmuError::Write { path: lib, source })
    })();
    if !keep {
        let _ = std::fs::remove_dir_all(&dir);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identifiers_are_c_identifiers() {
        assert_eq!(model_identifier(Path::new("out/adhesion.fmu")), "adhesion");
        assert_eq!(model_identifier(Path::new("my model-2.fmu")), "my_model_2");
        assert_eq!(model_identifier(Path::new("2026.fmu")), "fmu_2026");
    }

    #[test]
    fn guids_are_braced_and_follow_the_bytes_and_the_tool() {
        let g = guid_of(b"a", "railgrip 1");
        assert_eq!(g.len(), 38);
        assert!(g.starts_with('{') && g.ends_with('}'));
        assert_ne!(g, guid_of(b"b", "railgrip 1"));
        assert_ne!(g, guid_of(b"a", "railgrip 2"));
        assert_eq!(g, guid_of(b"a", "railgrip 1"));
    }
}
