fn main() {
    restore_broken_pipe_default();
    std::process::exit(longstep::cli::main());
}

/// A reader that closes the pipe early (`longstep check … | head`) ends the program quietly,
/// as it ends any Unix tool, instead of a panic in `println!` on the broken pipe: Rust
/// starts programs with SIGPIPE ignored, so put back the default action.
fn restore_broken_pipe_default() {
    #[cfg(unix)]
    // SAFETY: called first thing in `main`, before any thread exists; it only restores the
    // default disposition of one signal.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
