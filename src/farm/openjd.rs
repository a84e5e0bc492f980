//! Open Job Description (the template format AWS Deadline Cloud runs): a render step
//! whose parameter space is frames × tiles, and a merge step per frame that depends on
//! it. Commands are argument arrays, so no shell sees the paths. Checked with
//! `openjd check` and run locally with `openjd run` in CI; not tried on a real Deadline
//! farm.

use super::FarmJob;
use anyhow::{bail, Result};
use serde_json::json;
use std::path::{Path, PathBuf};

/// Writes `dir/job.template.json` and returns its path.
pub fn write(job: &FarmJob, job_file: &Path, dir: &Path) -> Result<PathBuf> {
    let nimbus = job.nimbus.display().to_string();
    let job_arg = job_file.display().to_string();
    for p in [&nimbus, &job_arg] {
        // `{{` opens a template expression in every string of the template.
        if p.contains("{{") {
            bail!("{p}: a path containing '{{{{' cannot go into an Open Job Description template");
        }
    }
    let frames = format!("{}-{}", job.first_frame, job.last_frame);
    let template = json!({
        "specificationVersion": "jobtemplate-2023-09",
        "name": "nimbus render",
        "steps": [
            {
                "name": "Render",
                "parameterSpace": {
                    "taskParameterDefinitions": [
                        {"name": "Frame", "type": "INT", "range": frames},
                        {"name": "Tile", "type": "INT", "range": format!("0-{}", job.tiles - 1)}
                    ]
                },
                "script": {
                    "actions": {
                        "onRun": {
                            "command": nimbus,
                            "args": ["farm", "task", "--job", job_arg,
                                     "--frame", "{{Task.Param.Frame}}", "--tile", "{{Task.Param.Tile}}"]
                        }
                    }
                }
            },
            {
                "name": "Merge",
                "dependencies": [{"dependsOn": "Render"}],
                "parameterSpace": {
                    "taskParameterDefinitions": [
                        {"name": "Frame", "type": "INT", "range": frames}
                    ]
                },
                "script": {
                    "actions": {
                        "onRun": {
                            "command": nimbus,
                            "args": ["farm", "merge", "--job", job_arg, "--frame", "{{Task.Param.Frame}}"]
                        }
                    }
                }
            }
        ]
    });
    let path = dir.join("job.template.json");
    crate::output::products::write_json(&path, &template)?;
    Ok(path)
}
