"""Every command the README shows runs as written (issue 27 item 8).

The commands are those of README.md's ```sh blocks and of the docs/ pages' ```sh blocks
marked runnable (``<!-- runnable ... -->`` on the line before). A document's blocks run
in order in one scratch folder, as a user following it would type them, with:

- ``./dev arduinobot`` and ``arduinobot``: this checkout's command line
  (``python -m arduinobot.cli.main`` in the interpreter that runs the tests), through a shim on
  PATH. ``./dev test ...`` is this suite itself, so it is not run from inside it.
- ``HOME``: a scratch folder whose ``~/ws/src`` is a course-like colcon workspace
  (tests/helpers/course_workspace.py), the one the own-robot commands name.
- The endpoint: the README names the default one, tcp/127.0.0.1:7447. The test does not
  take that port (a user's service may hold it); it runs a real `arduinobot serve` on a
  free loopback port and rewrites only the endpoint: tcp/127.0.0.1:7447 becomes that
  port, and a command that would use the default (plan, fk, ik, check-state, execute,
  view --follow) gets ``--connect`` to it. A ``serve`` the README shows listens on a free
  port of its own (its ``--listen`` rewritten, or given).
- ``/dev/ttyACM0``: a pty whose far end the test reads, as the Arduino would.
- Commands that block (``serve``, ``view`` without ``--plot-png`` or ``--png``) are started, checked
  for their ready line, then stopped with Ctrl-C; the others run in bash with
  ``set -euo pipefail``, consecutive ones in one script (so ``&`` and ``wait`` work).
"""

from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import threading
import time
import tty
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.helpers.procs import stop_process
from tests.helpers.serve import REPO, Server, start_server

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
SERIAL_PORT = "/dev/ttyACM0"
#: the documents whose commands run, and whether all their ```sh blocks do (README) or
#: only those marked runnable
DOCUMENTS = {"README.md": True, "docs/service.md": False, "docs/viewer.md": False}
#: commands shown but not run here, and why
NOT_RUN = {
    "./dev test": "the test suite itself",
    './dev test -m "not slow"': "the test suite itself",
}
#: what a blocking command prints once it is up
READY = {"serve": re.compile(r"service ready: instance "),
         "view": re.compile(r"arduinobot view: \S+ at http://127\.0\.0\.1:\d+")}
SERIAL_MESSAGE = re.compile(rb"b\d{3},s\d{3},e\d{3},g\d{3},")

SHIM = '''#!{python}
"""`arduinobot` for tests/test_readme.py: this checkout's CLI, with the endpoint
rewritten (see the test's docstring)."""
import os, socket, sys

def free_endpoint():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return "tcp/127.0.0.1:%d" % s.getsockname()[1]

service = os.environ["README_SERVICE"]
args = sys.argv[1:]
i = next((k for k, a in enumerate(args) if not a.startswith("-")), len(args))
command = args[i] if i < len(args) else ""
if command == "serve":
    args = [free_endpoint() if a.startswith("tcp/127.0.0.1:") else a for a in args]
    if not {{"--listen", "--connect", "--config", "--mode"}} & set(args):
        args[i + 1:i + 1] = ["--listen", free_endpoint()]
else:
    args = [a.replace("{default}", service) for a in args]
    uses_service = (command in ("fk", "ik", "check-state", "execute")
                    or (command == "plan" and "--local" not in args)
                    or (command == "view" and "--follow" in args))
    if uses_service and "--connect" not in args:
        args[i + 1:i + 1] = ["--connect", service]
os.execv(sys.executable, [sys.executable, "-m", "arduinobot.cli.main", *args])
'''


@dataclass(frozen=True)
class Command:
    """One logical command of a block (continuation lines joined, a here-document kept
    whole), with the line of the document it starts on."""

    text: str
    line: int

    @property
    def words(self) -> list[str]:
        w = self.text.split()
        return w[1:] if w[:2] == ["./dev", "arduinobot"] else w

    @property
    def blocking(self) -> str | None:
        """``serve`` or ``view`` when the command runs until stopped."""
        w = self.words
        if w[:2] == ["arduinobot", "serve"]:
            return "serve"
        if w[:2] == ["arduinobot", "view"] and not {"--plot-png", "--png"} & set(w):
            return "view"
        return None

    @property
    def bare(self) -> str:
        """The command without its trailing comment."""
        return re.sub(r"\s+#.*$", "", self.text)


def sh_blocks(doc: str, *, every: bool) -> Iterator[tuple[int, list[str]]]:
    """(first line number, lines) of each ```sh block (``every``: or only those marked
    runnable)."""
    lines = (REPO / doc).read_text("utf-8").splitlines()
    i = 0
    while i < len(lines):
        if lines[i].strip() == "```sh":
            before = next((ln for ln in reversed(lines[:i]) if ln.strip()), "")
            end = next(k for k in range(i + 1, len(lines)) if lines[k].strip() == "```")
            indent = len(lines[i]) - len(lines[i].lstrip())
            if every or before.strip().startswith("<!-- runnable"):
                yield i + 2, [ln[indent:] for ln in lines[i + 1:end]]
            i = end
        i += 1


def commands(first: int, lines: list[str]) -> list[Command]:
    out: list[Command] = []
    i = 0
    while i < len(lines):
        start, text = i, lines[i]
        heredoc = re.search(r"<<-?'?(\w+)'?", text)
        if heredoc:
            end = next(k for k in range(i + 1, len(lines)) if lines[k] == heredoc.group(1))
            text = "\n".join(lines[i:end + 1])
            i = end
        else:
            while text.endswith("\\"):
                i += 1
                text = text[:-1].rstrip() + " " + lines[i].strip()
        i += 1
        if text.strip() and not text.lstrip().startswith("#"):
            out.append(Command(text.strip(), first + start))
    return out


def document_commands(doc: str) -> list[Command]:
    return [c for first, lines in sh_blocks(doc, every=DOCUMENTS[doc])
            for c in commands(first, lines)]


class PtyReader:
    """The far end of a pty pair: the slave is the 'Arduino' port, raw mode."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.data = bytearray()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            if select.select([self.master], [], [], 0.02)[0]:
                self.data += os.read(self.master, 4096)

    def close(self) -> bytes:
        self._stop.set()
        self._thread.join()
        os.close(self.master)
        os.close(self.slave)
        return bytes(self.data)


@pytest.fixture(scope="module")
def readme_service() -> Iterator[Server]:
    """The README's `arduinobot serve` (its own: the README's commands move its robot)."""
    srv = start_server(["--workers", "1"])
    yield srv
    srv.stop()


@pytest.fixture(scope="module")
def home(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A HOME whose ~/ws is a course-like workspace."""
    from tests.helpers.course_workspace import make_course_workspace
    home = tmp_path_factory.mktemp("home")
    make_course_workspace(home / "ws")
    return home


def _environment(home: Path, bin_dir: Path, service: str) -> dict[str, str]:
    real_home = Path.home()
    cache = os.environ.get("ARDUINOBOT_CACHE") or str(
        Path(os.environ.get("XDG_CACHE_HOME") or real_home / ".cache") / "arduinobot")
    return {**os.environ, "HOME": str(home), "PATH": f"{bin_dir}:{os.environ['PATH']}",
            "PYTHONPATH": str(REPO), "PYTHONUNBUFFERED": "1", "README_SERVICE": service,
            # the caches the rest of the suite uses: a new HOME need not rebuild them
            "ARDUINOBOT_CACHE": cache,
            "MPLCONFIGDIR": os.environ.get("MPLCONFIGDIR",
                                           str(real_home / ".config" / "matplotlib"))}


def _shim(bin_dir: Path) -> None:
    bin_dir.mkdir(exist_ok=True)
    shim = bin_dir / "arduinobot"
    shim.write_text(SHIM.format(python=sys.executable, default=DEFAULT_ENDPOINT))
    shim.chmod(0o755)


def _as_typed(cmd: Command, serial: str) -> str:
    """The command for bash: `./dev arduinobot` is `arduinobot` (the shim); the serial
    port is the pty."""
    return cmd.text.replace("./dev arduinobot ", "arduinobot ").replace(SERIAL_PORT, serial)


def _run_script(cmds: list[Command], *, cwd: Path, env: dict[str, str], serial: str,
                doc: str) -> None:
    script = "\n".join(["set -euo pipefail",
                        "trap 'echo \"failed: $BASH_COMMAND\" >&2' ERR",
                        *(_as_typed(c, serial) for c in cmds)])
    r = subprocess.run(["bash", "-c", script], cwd=cwd, env=env, capture_output=True,
                       text=True, timeout=900)
    assert r.returncode == 0, (f"{doc} lines {cmds[0].line}-{cmds[-1].line} exited "
                               f"{r.returncode}:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")


def _run_blocking(cmd: Command, *, cwd: Path, env: dict[str, str], doc: str) -> str:
    """Start ``cmd``, wait for its ready line, stop it with Ctrl-C; returns the line."""
    proc = subprocess.Popen(["bash", "-c", "exec " + _as_typed(cmd, SERIAL_PORT)],
                            cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    ready = threading.Event()
    pattern = READY[cmd.blocking]  # type: ignore[index]

    def pump() -> None:
        for line in proc.stdout:  # type: ignore[union-attr]
            lines.append(line.rstrip("\n"))
            if pattern.search(line):
                ready.set()

    threading.Thread(target=pump, daemon=True).start()
    deadline = time.monotonic() + 300
    try:
        while not ready.wait(0.2):
            assert proc.poll() is None and time.monotonic() < deadline, (
                f"{doc} line {cmd.line}: `{cmd.bare}` never got ready "
                f"(exit {proc.poll()}):\n" + "\n".join(lines[-30:]))
    finally:
        code = stop_process(proc, signal.SIGINT, timeout=30)
    assert code in (0, 130, -signal.SIGINT), (
        f"{doc} line {cmd.line}: `{cmd.bare}` stopped with {code}:\n" + "\n".join(lines[-30:]))
    return next(ln for ln in lines if pattern.search(ln))


def test_the_readme_guides_and_keeps_its_setup_commands() -> None:
    text = (REPO / "README.md").read_text("utf-8")
    assert len(text.splitlines()) <= 200
    typed = [c.bare for c in document_commands("README.md")]
    # the two set-up commands stay exactly as they are
    assert "./dev arduinobot serve" in typed and "./dev test" in typed
    assert set(NOT_RUN) <= set(typed)  # what is not run is still shown
    # the guide comes before the reference: Quick start is the first section
    assert re.findall(r"^## (.+)$", text, flags=re.M)[0] == "Quick start"


def test_the_extraction_sees_every_kind_of_command() -> None:
    """Continuations are joined, here-documents kept whole, comments dropped."""
    cmds = document_commands("README.md")
    serve = [c for c in cmds if "--moveit-config" in c.text and c.blocking == "serve"]
    assert len(serve) == 1 and "\\" not in serve[0].text
    heredoc = next(c for c in cmds if c.text.startswith("cat > req.json"))
    assert heredoc.text.endswith("\nEOF") and '"goal"' in heredoc.text
    assert not any(c.text.startswith("#") for c in cmds)
    assert [c.bare for c in document_commands("docs/service.md")][-1] == \
        "arduinobot plan --request full.json"


@pytest.mark.slow
@pytest.mark.parametrize("doc", list(DOCUMENTS))
def test_every_command_runs_as_written(doc: str, readme_service: Server, home: Path,
                                       tmp_path: Path) -> None:
    bin_dir = tmp_path / "bin"
    _shim(bin_dir)
    cwd = tmp_path / "work"
    cwd.mkdir()
    env = _environment(home, bin_dir, readme_service.endpoint)
    cmds = [c for c in document_commands(doc) if c.bare not in NOT_RUN]
    assert cmds
    arm = PtyReader()
    try:
        pending: list[Command] = []
        for cmd in [*cmds, None]:
            if cmd is None or cmd.blocking:
                if pending:
                    _run_script(pending, cwd=cwd, env=env, serial=arm.path, doc=doc)
                    pending = []
                if cmd is not None:
                    _run_blocking(cmd, cwd=cwd, env=env, doc=doc)
            else:
                pending.append(cmd)
    finally:
        sent = arm.close()
    if any(SERIAL_PORT in c.text for c in cmds):
        # the real-arm command streamed the course protocol to the port
        assert SERIAL_MESSAGE.search(sent), sent[:200]
        assert not SERIAL_MESSAGE.sub(b"", sent), sent[:200]
    if doc == "README.md":
        for out in ("traj.json", "traj.png", "sim.png", "plots.png", "arduinobot.urdf"):
            assert (cwd / out).stat().st_size > 0, out


def test_links_between_the_pages_resolve() -> None:
    """README.md, CONTRIBUTING.md and docs/ link to files that exist, and the README's
    table of contents to its own sections."""
    pages = [REPO / "README.md", REPO / "CONTRIBUTING.md", *sorted((REPO / "docs").glob("*.md"))]
    assert len(pages) > 3
    for page in pages:
        text = page.read_text("utf-8")
        for target in re.findall(r"\]\(([^)#]+?)(?:#[^)]*)?\)", text):
            if not target.startswith(("http://", "https://")):
                assert (page.parent / target).exists(), f"{page.name}: {target}"
    text = (REPO / "README.md").read_text("utf-8")
    anchors = {re.sub(r"[^a-z0-9 -]", "", h.lower()).replace(" ", "-")
               for h in re.findall(r"^## (.+)$", text, flags=re.M)}
    assert set(re.findall(r"\]\(#([^)]+)\)", text)) <= anchors


def test_every_pip_install_the_pages_show_installs_from_the_clone_an_extra_that_exists(
        ) -> None:
    """arduinobot is not on PyPI: `pip install 'arduinobot[ros2]'` fails for a user (issue
    38, item 7); the pages say `pip install -e '.[EXTRA]'` with an extra pyproject.toml has,
    and name no set-up time they cannot back (item 9: '~40 s' took 104 s)."""
    # (tomllib is 3.11's; the project runs on 3.10) the table's keys: `name = [`
    table = (REPO / "pyproject.toml").read_text("utf-8").split(
        "[project.optional-dependencies]")[1].split("\n[")[0]
    extras = set(re.findall(r"^([\w-]+) = \[", table, flags=re.M))
    assert {"ros2", "sim", "view", "see"} <= extras
    pages = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
    seen = 0
    for page in pages:
        for line in page.read_text("utf-8").splitlines():
            for m in re.finditer(r"pip install ([^`\n;)]*\[[^\]]*\][^`\s;)]*)", line):
                spec = m.group(1).strip()
                assert spec.startswith("-e '.["), f"{page.name}: `pip install {spec}`"
                named = re.search(r"\[([^\]]*)\]", spec)
                assert named and set(named.group(1).split(",")) <= extras, \
                    f"{page.name}: `pip install {spec}` ({sorted(extras)})"
                seen += 1
    assert seen >= 3
    quick = (REPO / "README.md").read_text("utf-8").split("## Your first plans")[0]
    assert not re.search(r"~\s*\d+\s*s\b", quick)
