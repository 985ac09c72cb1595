//! Where a campaign's outputs go: every path below the output folder is spelled here and
//! nowhere else.
//!
//! ```text
//! <out>/runs/<run>/estimates.parquet   the run's estimates table (README, "Estimates table")
//! <out>/runs/<run>/run.json            its RunRecord, with the SHA-256 of its inputs
//! <out>/summary.csv, summary.parquet   one row per run (SUMMARY_COLUMNS)
//! <out>/models/                        mlp.json, mlp.h, mlp.history.csv, mlp.polach.json,
//!                                      mlp.polach.h, mlp.polach-fits.json (ModelPaths)
//! <out>/campaign.json                  the CampaignRecord the report is rebuilt from
//! <out>/report/index.html              the validation report
//! ```

use std::path::{Path, PathBuf};

/// The output folder of `railgrip run`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OutDir {
    root: PathBuf,
}

impl OutDir {
    pub fn new(root: impl Into<PathBuf>) -> OutDir {
        OutDir { root: root.into() }
    }
    pub fn root(&self) -> &Path {
        &self.root
    }
    /// The folder of per-run outputs.
    pub fn runs(&self) -> PathBuf {
        self.root.join("runs")
    }
    /// The folder of one run's outputs.
    pub fn run_dir(&self, run: &str) -> PathBuf {
        self.runs().join(run)
    }
    pub fn run_record(&self, run: &str) -> PathBuf {
        self.run_dir(run).join("run.json")
    }
    /// The run's estimates table; its stem is [`OutDir::ESTIMATES_STEM`].
    pub fn run_estimates(&self, run: &str) -> PathBuf {
        self.run_dir(run)
            .join(format!("{}.parquet", Self::ESTIMATES_STEM))
    }
    pub const ESTIMATES_STEM: &'static str = "estimates";
    pub fn summary_csv(&self) -> PathBuf {
        self.root.join("summary.csv")
    }
    pub fn summary_parquet(&self) -> PathBuf {
        self.root.join("summary.parquet")
    }
    pub fn campaign_record(&self) -> PathBuf {
        self.root.join("campaign.json")
    }
    /// The campaign's model files (name `mlp`).
    pub fn models(&self) -> ModelPaths {
        ModelPaths::new(self.root.join("models"), "mlp")
    }
    pub fn report_dir(&self) -> PathBuf {
        self.root.join("report")
    }
    pub fn report_html(&self) -> PathBuf {
        self.report_dir().join("index.html")
    }
}

/// The files of one set of models named `name` in `dir` (`railgrip train --out DIR --name
/// NAME`, or a campaign's `models/` with name `mlp`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModelPaths {
    pub dir: PathBuf,
    pub name: String,
}

impl ModelPaths {
    pub fn new(dir: impl Into<PathBuf>, name: &str) -> ModelPaths {
        ModelPaths {
            dir: dir.into(),
            name: name.to_string(),
        }
    }
    fn file(&self, suffix: &str) -> PathBuf {
        self.dir.join(format!("{}{suffix}", self.name))
    }
    /// The network model file.
    pub fn mlp(&self) -> PathBuf {
        self.file(".json")
    }
    /// Its C header (symbol prefix [`ModelPaths::mlp_prefix`]).
    pub fn mlp_header(&self) -> PathBuf {
        self.file(".h")
    }
    pub fn history_csv(&self) -> PathBuf {
        self.file(".history.csv")
    }
    /// The Polach model file.
    pub fn polach(&self) -> PathBuf {
        self.file(".polach.json")
    }
    /// Its C header (symbol prefix [`ModelPaths::polach_prefix`]).
    pub fn polach_header(&self) -> PathBuf {
        self.file(".polach.h")
    }
    /// Every Polach fit (pooled, per run, per temperature) and k(T).
    pub fn polach_fits(&self) -> PathBuf {
        self.file(".polach-fits.json")
    }
    pub fn mlp_prefix(&self) -> String {
        self.name.clone()
    }
    pub fn polach_prefix(&self) -> String {
        format!("{}_polach", self.name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_are_the_documented_ones() {
        let o = OutDir::new("/o");
        assert_eq!(
            o.run_estimates("r"),
            Path::new("/o/runs/r/estimates.parquet")
        );
        assert_eq!(o.run_record("r"), Path::new("/o/runs/r/run.json"));
        assert_eq!(o.report_html(), Path::new("/o/report/index.html"));
        let m = o.models();
        assert_eq!(m.polach_header(), Path::new("/o/models/mlp.polach.h"));
        assert_eq!(m.polach_fits(), Path::new("/o/models/mlp.polach-fits.json"));
        assert_eq!(m.polach_prefix(), "mlp_polach");
    }
}
