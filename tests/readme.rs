//! Every command of README.md, run as written, in order, in a scratch copy of
//! the repository's `api/` and `docs/`, against the real binary and a real
//! server on loopback.
//!
//! The README's ```sh blocks are split into commands (continuation lines,
//! here-documents and `for`/`until`/`while` loops are one command each;
//! comment lines are not commands) and run by one `bash -e` script, so a
//! variable set by one command (`ID=$(curl …)`) is seen by the next. After
//! each command the script records its number; the test asserts that every
//! extracted command ran and succeeded.
//!
//! The harness changes no command. It provides what a fresh machine has:
//! - `cargo` is a shim for the four cargo commands the README uses, each
//!   mapped to what it does once the release build exists (the binary under
//!   test is the one `cargo run --release` runs): `run --release -- ARGS`
//!   runs it, `install --path .` copies it into `$CARGO_INSTALL_ROOT/bin`
//!   (a scratch directory on `PATH`, before any `polbrdf` already installed),
//!   `build --release` checks it exists, and `test --release` checks that
//!   `.ci/run` runs exactly that command (this test is part of it).
//! - A command that starts the server (`… serve`) runs in the background on
//!   a free port (`POLBRDF_LISTEN`, as docs/service.md documents) and the
//!   script waits for `/readyz`; `URL` names that port for the curl commands
//!   (the README's `URL=${URL:-http://127.0.0.1:8080}`). A second `serve`
//!   replaces the first.
//! - `pip install ./python` builds and installs the Python package from the
//!   repository's `python/` into a virtual environment of the scratch
//!   directory (the run's build directory reused), and `python3` is then
//!   that environment's interpreter (`pip` and `python3` shims).
//! - Long work is shortened only by the variables the README shows
//!   (`BENCH_STREAMS`, `BENCH_REPEAT`, `BENCH_X`, `SPP`).

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

/// The commands of the ```sh blocks of a Markdown text, in order.
fn commands(markdown: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut in_block = false;
    let mut current: Vec<&str> = Vec::new();
    // What closes the command being collected.
    enum Open {
        None,
        Continued,
        HereDoc(String),
        Loop(usize),
    }
    let mut open = Open::None;
    for line in markdown.lines() {
        let t = line.trim();
        if !in_block {
            in_block = t == "```sh";
            continue;
        }
        if t == "```" && matches!(open, Open::None) {
            in_block = false;
            continue;
        }
        assert!(t != "```", "README: a ```sh block ends inside a command");
        if matches!(open, Open::None) && (t.is_empty() || t.starts_with('#')) {
            continue;
        }
        current.push(line);
        open = match open {
            Open::HereDoc(tag) if t == tag => Open::None,
            o @ Open::HereDoc(_) => o,
            Open::Loop(depth) => {
                let d = depth + loop_opens(t) - usize::from(t == "done" || t.starts_with("done "));
                if d == 0 { Open::None } else { Open::Loop(d) }
            }
            Open::None | Open::Continued => {
                if let Some(tag) = here_doc_tag(t) {
                    Open::HereDoc(tag)
                } else if loop_opens(t) > 0 && !t.contains("done") {
                    Open::Loop(loop_opens(t))
                } else if t.ends_with('\\') {
                    Open::Continued
                } else {
                    Open::None
                }
            }
        };
        if matches!(open, Open::None) {
            out.push(current.join("\n"));
            current.clear();
        }
    }
    assert!(current.is_empty(), "README: unfinished command {current:?}");
    out
}

/// 1 when the line opens a `for`/`while`/`until` loop.
fn loop_opens(t: &str) -> usize {
    usize::from(
        ["for ", "while ", "until "]
            .iter()
            .any(|k| t.starts_with(k)),
    )
}

/// The delimiter of a here-document started on this line (`<<'EOF'`, `<<EOF`).
fn here_doc_tag(t: &str) -> Option<String> {
    let rest = &t[t.find("<<")? + 2..];
    let tag: String = rest
        .trim_start_matches('-')
        .trim()
        .trim_matches(|c| c == '\'' || c == '"')
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect();
    (!tag.is_empty()).then_some(tag)
}

/// True for a command that starts the service.
fn starts_server(cmd: &str) -> bool {
    let words: Vec<&str> = cmd.split_whitespace().collect();
    words.contains(&"serve") && (words[0] == "cargo" || words[0] == "polbrdf")
}

#[test]
fn the_splitter_keeps_here_documents_loops_and_continuations_whole() {
    let md = "text\n```sh\n# comment\na --x \\\n  --y\ncat > f <<'EOF'\n{\"a\": 1}\n# not a comment here\nEOF\nfor t in 1 2; do\n  echo $t\ndone\nuntil b; do sleep 1; done\nc | d\n```\n```json\n{}\n```\n";
    let c = commands(md);
    assert_eq!(c.len(), 5, "{c:#?}");
    assert_eq!(c[0], "a --x \\\n  --y");
    assert!(c[1].ends_with("# not a comment here\nEOF"), "{}", c[1]);
    assert_eq!(c[2], "for t in 1 2; do\n  echo $t\ndone");
    assert_eq!(c[3], "until b; do sleep 1; done");
    assert_eq!(c[4], "c | d");
    assert!(starts_server("cargo run --release -- serve"));
    assert!(!starts_server("polbrdf solve serve.json"));
}

/// The `cargo` stand-in described in the module documentation.
fn cargo_shim(bin: &Path, ci_run: &Path) -> String {
    format!(
        r#"#!/usr/bin/env bash
set -e
case "$*" in
  "run --release -- "*) shift 3; exec "{bin}" "$@" ;;
  "install --path .")
    mkdir -p "$CARGO_INSTALL_ROOT/bin"
    cp "{bin}" "$CARGO_INSTALL_ROOT/bin/polbrdf"
    echo "readme: installed $CARGO_INSTALL_ROOT/bin/polbrdf" ;;
  "build --release") test -x "{bin}" ;;
  "test --release")
    grep -qx 'cargo test --release' "{ci}"
    echo "readme: 'cargo test --release' is what .ci/run runs (this test is part of it)" ;;
  *) echo "readme: 'cargo $*' is not a command this harness can run" >&2; exit 1 ;;
esac
"#,
        bin = bin.display(),
        ci = ci_run.display()
    )
}

/// The `pip` and `python3` stand-ins: `pip install ./python` builds the
/// package from this repository's `python/` (maturin, in a virtual
/// environment of the scratch directory, the run's build directory reused)
/// and `python3` is then that environment's interpreter. The build runs with
/// the real `cargo` on `PATH`, not the harness's shim.
fn python_shims(repo: &Path, venv: &Path, target: &Path) -> (String, String) {
    let pip = format!(
        r#"#!/usr/bin/env bash
set -e
case "$*" in
  "install ./python")
    if [ ! -x "{venv}/bin/python" ]; then
      /usr/bin/env -u VIRTUAL_ENV PATH="$READ_ME_SYSTEM_PATH" python3 -m venv "{venv}"
      "{venv}/bin/pip" install -q --disable-pip-version-check 'maturin>=1.7,<2' numpy
    fi
    PATH="{venv}/bin:$READ_ME_SYSTEM_PATH" CARGO_TARGET_DIR="{target}" "{venv}/bin/pip" install -q --disable-pip-version-check --no-build-isolation "{repo}/python"
    echo "readme: built and installed polbrdf from {repo}/python" ;;
  *) echo "readme: 'pip $*' is not a command this harness can run" >&2; exit 1 ;;
esac
"#,
        venv = venv.display(),
        target = target.display(),
        repo = repo.display()
    );
    let python = format!(
        r#"#!/usr/bin/env bash
test -x "{venv}/bin/python" || {{ echo "readme: python3 before 'pip install ./python'" >&2; exit 1; }}
exec "{venv}/bin/python" "$@"
"#,
        venv = venv.display()
    );
    (pip, python)
}

fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_tree(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), &target).unwrap();
        }
    }
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

#[test]
fn every_readme_command_runs() {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(repo.join("README.md")).unwrap();
    let cmds = commands(&readme);
    assert!(cmds.len() >= 30, "README commands found: {}", cmds.len());

    let dir = common::scratch_dir("readme");
    for sub in ["api", "docs"] {
        copy_tree(&repo.join(sub), &dir.join(sub));
    }
    let shim_dir = dir.join("shim");
    std::fs::create_dir_all(&shim_dir).unwrap();
    let shim = shim_dir.join("cargo");
    std::fs::write(
        &shim,
        cargo_shim(
            Path::new(env!("CARGO_BIN_EXE_polbrdf")),
            &repo.join(".ci/run"),
        ),
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&shim, std::fs::Permissions::from_mode(0o755)).unwrap();
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo.join("target"));
    let (pip, python) = python_shims(&repo, &dir.join("python-venv"), &target);
    for (name, text) in [("pip", pip), ("python3", python)] {
        let p = shim_dir.join(name);
        std::fs::write(&p, text).unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
    }

    let done = dir.join("done.txt");
    let mut script = String::from(
        r#"set -e
readme_serve() {
  if [ -n "${SERVER_PID:-}" ]; then kill "$SERVER_PID"; wait "$SERVER_PID" || true; fi
  "$@" > server.log 2>&1 &
  SERVER_PID=$!
  for _ in $(seq 1 600); do
    if curl -sf "$URL/readyz" > /dev/null; then return 0; fi
    if ! kill -0 "$SERVER_PID" 2> /dev/null; then cat server.log >&2; return 1; fi
    sleep 0.1
  done
  echo "readme: the server did not become ready" >&2; return 1
}
trap 'if [ -n "${SERVER_PID:-}" ]; then kill "$SERVER_PID" 2> /dev/null || true; fi' EXIT
"#,
    );
    for (i, c) in cmds.iter().enumerate() {
        script.push_str(&format!("echo '@@ readme command {}:' >&2\n", i + 1));
        if starts_server(c) {
            script.push_str(&format!("readme_serve {c}\n"));
        } else {
            script.push_str(c);
            script.push('\n');
        }
        script.push_str(&format!("echo {} >> \"{}\"\n", i + 1, done.display()));
    }
    let port = free_port();
    let path = format!(
        "{}:{}:{}",
        shim_dir.display(),
        dir.join("cargo-root/bin").display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let out = Command::new("bash")
        .arg("-c")
        .arg(&script)
        .current_dir(&dir)
        .env("PATH", path)
        .env("CARGO_INSTALL_ROOT", dir.join("cargo-root"))
        .env(
            "READ_ME_SYSTEM_PATH",
            std::env::var("PATH").unwrap_or_default(),
        )
        .env("POLBRDF_LISTEN", format!("127.0.0.1:{port}"))
        .env("URL", format!("http://127.0.0.1:{port}"))
        .env("BENCH_STREAMS", "4,8")
        .env("BENCH_REPEAT", "1")
        .env("BENCH_X", "1,10,100")
        .env("SPP", "4")
        .output()
        .expect("bash");
    let ran = std::fs::read_to_string(&done).unwrap_or_default();
    let ran = ran.lines().count();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let tail: String = stderr
        .lines()
        .rev()
        .take(40)
        .collect::<Vec<_>>()
        .into_iter()
        .rev()
        .collect::<Vec<_>>()
        .join("\n");
    assert!(
        out.status.success() && ran == cmds.len(),
        "README: {ran} of {} commands succeeded; command {} was\n{}\nstderr (end):\n{tail}",
        cmds.len(),
        ran + 1,
        cmds.get(ran).map_or("", |s| s.as_str())
    );
    eprintln!("[readme] {ran} of {} README commands ran", cmds.len());
}
