//! `froctomap completions SHELL` and `froctomap man`: the shell completion script and the
//! manual page, both generated from the command-line definition so they never drift from it.

use anyhow::Result;
use clap::Command;
use std::io::Write;

/// Writes the completion script of `shell` for `command` to standard output.
pub fn completions(mut command: Command, shell: clap_complete::Shell) -> Result<()> {
    let name = command.get_name().to_string();
    // Rendered in memory first: the generator panics on a failed write (a closed pipe).
    let mut script = Vec::new();
    clap_complete::generate(shell, &mut command, name, &mut script);
    std::io::stdout().lock().write_all(&script)?;
    Ok(())
}

/// Writes the manual page (roff, section 1) of `command` to standard output.
pub fn man(command: Command) -> Result<()> {
    let mut page = Vec::new();
    clap_mangen::Man::new(command).render(&mut page)?;
    std::io::stdout().lock().write_all(&page)?;
    Ok(())
}
