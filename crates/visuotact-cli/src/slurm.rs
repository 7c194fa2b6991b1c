//! `sweep --slurm N`: the scripts that run a sweep as a SLURM array of shards and merge it —
//! the same command line as given, less `--slurm`, plus `--shard $SLURM_ARRAY_TASK_ID/N`.

use std::path::Path;

use anyhow::Context;

/// `s` quoted for a POSIX shell.
fn quoted(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// This run's arguments without `--slurm N` and `--slurm-cpus N`.
fn sweep_args() -> Vec<String> {
    let mut out = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--slurm" | "--slurm-cpus" => {
                args.next();
            }
            _ if a.starts_with("--slurm=") || a.starts_with("--slurm-cpus=") => {}
            _ => out.push(a),
        }
    }
    out
}

/// Writes `sweep.sbatch`, `merge.sbatch` and `submit.sh` into `output`.
pub(crate) fn write_scripts(
    output: &Path,
    n: usize,
    cpus: usize,
    keep: usize,
) -> anyhow::Result<()> {
    anyhow::ensure!(n >= 1, "--slurm: at least 1 array task");
    std::fs::create_dir_all(output)
        .with_context(|| format!("{}: cannot create folder", output.display()))?;
    let out = std::path::absolute(output)?;
    let exe = std::env::current_exe().context("the visuotact binary's path")?;
    let cwd = std::env::current_dir()?;
    let q = |p: &Path| quoted(&p.display().to_string());
    let args: Vec<String> = sweep_args().iter().map(|a| quoted(a)).collect();
    let array = format!(
        "#!/bin/bash\n\
         #SBATCH --job-name=visuotact-sweep\n\
         #SBATCH --array=1-{n}\n\
         #SBATCH --cpus-per-task={cpus}\n\
         #SBATCH --chdir={cwd}\n\
         #SBATCH --output={out}/slurm-%A_%a.out\n\
         set -euo pipefail\n\
         export RAYON_NUM_THREADS=\"${{SLURM_CPUS_PER_TASK:-{cpus}}}\"\n\
         exec {exe} {args} --shard \"${{SLURM_ARRAY_TASK_ID}}/{n}\"\n",
        cwd = cwd.display(),
        out = out.display(),
        exe = q(&exe),
        args = args.join(" "),
    );
    let parts: Vec<String> = (1..=n)
        .map(|k| q(&out.join(format!("part-{k}-of-{n}.json"))))
        .collect();
    let merge = format!(
        "#!/bin/bash\n\
         #SBATCH --job-name=visuotact-sweep-merge\n\
         #SBATCH --chdir={cwd}\n\
         #SBATCH --output={out}/slurm-merge-%j.out\n\
         set -euo pipefail\n\
         exec {exe} sweep merge {parts} -o {outq} --keep {keep}\n",
        cwd = cwd.display(),
        out = out.display(),
        exe = q(&exe),
        parts = parts.join(" "),
        outq = q(&out),
    );
    let submit = "#!/bin/bash\n\
         # Submits the array of shards, then the merge once every shard has succeeded.\n\
         set -euo pipefail\n\
         cd \"$(dirname \"$0\")\"\n\
         array=$(sbatch --parsable sweep.sbatch)\n\
         sbatch --parsable --dependency=\"afterok:${array%%;*}\" merge.sbatch\n";
    for (name, text) in [
        ("sweep.sbatch", array.as_str()),
        ("merge.sbatch", merge.as_str()),
        ("submit.sh", submit),
    ] {
        let p = out.join(name);
        crate::write_atomically(&p, text)?;
        make_executable(&p)?;
    }
    note!(
        "wrote {0}/sweep.sbatch ({n} shards, {cpus} CPUs each), {0}/merge.sbatch and {0}/submit.sh; run {0}/submit.sh on the cluster's login node",
        out.display()
    );
    Ok(())
}

#[cfg(unix)]
fn make_executable(p: &Path) -> anyhow::Result<()> {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(p, std::fs::Permissions::from_mode(0o755))
        .with_context(|| format!("{}: cannot make executable", p.display()))
}

#[cfg(not(unix))]
fn make_executable(_: &Path) -> anyhow::Result<()> {
    Ok(())
}
