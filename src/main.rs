fn main() {
    std::process::exit(longstep::cli::main());
}
