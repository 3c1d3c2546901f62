//! Every data export a registered phenomenon declares is a `phenomena export` command,
//! offering the declared file formats.

use crate::run;

#[test]
fn every_export_of_the_registry_is_a_command() {
    let dir = tempfile::tempdir().unwrap();
    let mut seen = 0;
    for p in phenomena_scene::registry::PHENOMENA {
        for export in p.exports() {
            let out = run(dir.path(), &["export", export.name, "--help"]);
            let help = String::from_utf8_lossy(&out.stdout);
            assert!(out.status.success(), "{} exports {}, which is no command", p.name(), export.name);
            // A command with one format fixes it; one with several names each.
            if export.formats.len() > 1 {
                for f in export.formats {
                    assert!(help.contains(f), "export {}: format {f} not offered:\n{help}", export.name);
                }
            }
            seen += 1;
        }
    }
    assert!(seen >= 3, "only {seen} exports in the registry");
}
