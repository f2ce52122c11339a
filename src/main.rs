fn main() {
    std::process::exit(polbrdf::cli::main());
}
