//! The `rayproof` binary: parse, run, map errors to exit codes. The command-line layer (`cli/`)
//! lives here, outside the library's API: one file per command, argument definitions and printing.

use clap::error::ErrorKind;
mod cli;

use cli::{error_exit_code, one_line, parse, run};
use std::alloc::{GlobalAlloc, Layout, System};
use std::process::ExitCode;

/// The system's allocator, but an allocation that fails ends the run with one line and exit 71
/// ([`rayproof::output::out_of_memory`]) instead of an abort with a stack trace.
struct Allocator;

// SAFETY: every call is the system allocator's, with its arguments; a null it returns is never
// handed on (the run ends)
unsafe impl GlobalAlloc for Allocator {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(l) };
        if p.is_null() {
            rayproof::output::out_of_memory(l.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(l) };
        if p.is_null() {
            rayproof::output::out_of_memory(l.size());
        }
        p
    }

    unsafe fn realloc(&self, ptr: *mut u8, l: Layout, new: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, l, new) };
        if p.is_null() {
            rayproof::output::out_of_memory(new);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, l: Layout) {
        unsafe { System.dealloc(ptr, l) }
    }
}

#[global_allocator]
static GLOBAL: Allocator = Allocator;

fn main() -> ExitCode {
    // Usage errors: one line naming the argument, exit 2 (`diff`: 64, never a verdict's code);
    // idiff's spellings of `diff` taken
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    let usage = if args.get(1).is_some_and(|a| a == "diff") {
        cli::diff::EXIT_USAGE
    } else {
        2
    };
    let args = match cli::diff::idiff_spellings(args) {
        Ok(a) => a,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(usage);
        }
    };
    let cli = match parse(args) {
        Ok(cli) => cli,
        Err(e) if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) => {
            // A closed pipe (`rayproof --help | head`) is not an error
            use std::io::Write;
            let _ = write!(std::io::stdout(), "{e}");
            return ExitCode::SUCCESS;
        }
        Err(e) => {
            eprintln!("{}", one_line(&e));
            return ExitCode::from(usage);
        }
    };
    // An instruction-set cap the kernels cannot follow (RAYPROOF_ISA): one line, a usage
    // error's exit (2; `diff`: 64, where 2 is a comparison's FAILURE)
    if let Err(e) = rayproof::numerics::cpu::check_env() {
        eprintln!("error: {e}");
        return ExitCode::from(usage);
    }
    // A TERM or INT removes the temporaries of outputs being written
    rayproof::output::clean_up_on_signals();
    let result = run(cli);
    // An interrupted run ends in the signal handler (exit 130), never here
    rayproof::process::wait_if_interrupted();
    match result {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            // One line of plain text: line breaks (from a name or value read from a file, a
            // path: tests/fuzz_surfaces.rs) and other control characters (an outside
            // routine's ESC or NUL) shown escaped
            eprintln!(
                "error: {}",
                rayproof::images::escape_controls(&format!("{e:#}"))
            );
            ExitCode::from(error_exit_code(&e))
        }
    }
}
