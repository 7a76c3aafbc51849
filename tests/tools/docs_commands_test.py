#!/usr/bin/python3
"""Every command the pages show is accounted for, and those this machine can run are run as shown.

The pages are docs/**/*.md, README.md and CONTRIBUTING.md; their commands are the lines of their
```sh fenced blocks (a line ending in `\\` continues on the next; a line starting with `#` is a
comment). Each block is named below (BLOCKS: its page and its first command) with how it is
covered:

  * "here": this test runs its lines, extracted from the page, with the build's programs
    substituted for the paths the page gives (SUBSTITUTIONS), and judges each one's exit status
    and, where the page says what it prints, the key lines of that;
  * "test NAME": another test extracts the block from the page and runs it (vm_walkthrough for
    docs/guides/commission.md);
  * "not run: WHY": it needs what this machine or a test cannot give (a CAN bus, root on the
    host, systemd, a package install, a whole second build) — said, not faked.

A block on a page that BLOCKS does not name fails the test (a new command must be classified), and
so does a BLOCKS entry no page has any more (a moved command must be re-classified). Program code
is held to the same rule: the one ```js block, docs/guides/remote-sdo.md's node-canopen recipe, is
run by vm_remote (here it is parsed), and a ```python or other ```js block fails.

The "here" blocks talk DDS on loopback and LCM on 224.0.0.1 with ttl=0: run this test inside
tests/publish/in_private_net.sh, so that nothing else hears the demos it runs nor reaches them.

Usage: docs_commands_test.py SOURCE_DIR BUILD_DIR LCM_LOGGER [--list]
  --list  the classification only, nothing run
Prints one `ok:` / `FAILED:` line per judgement and ends with "N passed, N failed".
"""
import atexit
import glob
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

SRC, BUILD, LCM_LOGGER = (os.path.abspath(a) for a in sys.argv[1:4])
WORK = tempfile.mkdtemp(prefix="docs_commands.")
passed = failed = 0


def judge(ok, what, detail=""):
    global passed, failed
    if ok:
        passed += 1
        print(f"ok: {what}", flush=True)
    else:
        failed += 1
        print(f"FAILED: {what}" + (f"\n    {detail}" if detail else ""), flush=True)
    return ok


# ---- Extraction.

def doc_pages():
    """The pages whose blocks are accounted for, relative to the source tree."""
    pages = sorted(glob.glob(os.path.join(SRC, "docs", "**", "*.md"), recursive=True))
    pages += [os.path.join(SRC, "README.md"), os.path.join(SRC, "CONTRIBUTING.md")]
    return [os.path.relpath(p, SRC) for p in pages]


def blocks():
    """(page, line of the fence, [commands], heading) of every ```sh block, in page order; the
    heading is the last `# ` or `## ` line above it."""
    out = []
    for page in doc_pages():
        path = os.path.join(SRC, page)
        fence, cmds, cont, heading = None, [], False, ""
        with open(path, encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                line = line.rstrip("\n")
                m = re.match(r"^\s*```(\S*)\s*$", line)
                if m and fence is None:
                    fence, lang, cmds, cont = n, m.group(1), [], False
                    continue
                if m:
                    if lang == "sh":
                        out.append((page, fence, cmds, heading))
                    fence = None
                    continue
                if fence is None and re.match(r"^##? ", line):
                    heading = line
                if fence is None or lang != "sh":
                    continue
                text = line.strip()
                if cont:
                    cmds[-1] += "\n" + line
                elif text and not text.startswith("#"):
                    cmds.append(text)
                else:
                    continue
                cont = line.endswith("\\")
    return out


def first_command(cmds):
    """A block's name: its first command without a `$ ` prompt or a trailing comment."""
    c = cmds[0].split("\n")[0]
    c = c[2:] if c.startswith("$ ") else c
    return re.sub(r"\s+#.*$", "", c).strip()


# ---- Running a page's line as the page shows it, with the build's programs.

SUBSTITUTIONS = [
    (r"(?<![\w/.-])(\./)?build/examples/", BUILD + "/examples/"),
    (r"(?<![\w/.-])(\./)?build/programs/", BUILD + "/programs/"),
    (r"(?<![\w/.-])(\./)?build/man/", BUILD + "/man/"),
    (r"(?<![\w/.-])build/site\b", WORK + "/site"),  # mkdocs' output: not into the source tree
    (r"(?<![\w/.-])(\./)?scripts/", SRC + "/scripts/"),
    (r"(?<![\w/.-])(\./)?tests/tools/", SRC + "/tests/tools/"),
    (r"/etc/oegw/dds\b", WORK + "/dds"),  # the keys' folder: a temporary one
    (r"^oegw ", BUILD + "/programs/oegw "),
    (r"^lcm-logger ", LCM_LOGGER + " "),
    (r"^lcm-logplayer ", os.path.join(os.path.dirname(LCM_LOGGER), "lcm-logplayer") + " "),
]


def substitute(cmd):
    for pattern, repl in SUBSTITUTIONS:
        cmd = re.sub(pattern, lambda _m, r=repl: r, cmd)
    return cmd


def short(cmd):
    return cmd.split("\n")[0][:110]


class Bg:
    """A page's line started in the background (`&` at its end, a second terminal, Ctrl-C to stop)."""
    started = []  # every one, ended at exit if still running

    def __init__(self, cmd, name, cwd=WORK):
        self.cmd, self.out = cmd, os.path.join(WORK, name + ".out")
        line = substitute(cmd).rstrip()
        line = re.sub(r"\s*#.*$", "", line).rstrip()
        line = line[:-1] if line.endswith("&") else line
        # Its own process group, as a terminal's job: Ctrl-C (SIGINT) reaches the program itself.
        self.p = subprocess.Popen(["bash", "-c", "exec " + line], cwd=cwd, stdout=open(self.out, "w"),
                                  stderr=subprocess.STDOUT, start_new_session=True)
        Bg.started.append(self)

    def text(self):
        with open(self.out, encoding="utf-8", errors="replace") as f:
            return f.read()

    def wait_for(self, regex, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if re.search(regex, self.text(), re.M):
                return True
            if self.p.poll() is not None:
                return bool(re.search(regex, self.text(), re.M))
            time.sleep(0.1)
        return False

    def interrupt(self):
        if self.p.poll() is None:
            os.killpg(self.p.pid, signal.SIGINT)

    def wait(self, seconds):
        try:
            return self.p.wait(seconds)
        except subprocess.TimeoutExpired:
            os.killpg(self.p.pid, signal.SIGKILL)
            self.p.wait()
            return None


def run(cmd, timeout=60, cwd=WORK):
    """A page's line in the foreground: (exit status or None at the time-out, what it printed)."""
    try:
        r = subprocess.run(["bash", "-c", substitute(cmd)], cwd=cwd, stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, timeout=timeout, text=True, errors="replace")
        return r.returncode, r.stdout
    except subprocess.TimeoutExpired as e:
        out = e.stdout or ""
        return None, out.decode(errors="replace") if isinstance(out, bytes) else out


def expect_run(page, cmd, rc_want=0, lines=(), timeout=60, cwd=WORK, count=None):
    """Runs CMD; judges its exit status and that every regex of LINES has a line (COUNT: the
    number of lines matching the first one)."""
    rc, out = run(cmd, timeout, cwd)
    tail = " | ".join([l for l in out.split("\n") if "FAILED" in l] + out.strip().split("\n")[-4:])
    ok = judge(rc == rc_want, f"{page}: `{short(cmd)}` exits {rc_want}", f"exit {rc}; printed: {tail}")
    for i, rx in enumerate(lines):
        n = len(re.findall(rx, out, re.M))
        if i == 0 and count is not None:
            judge(n == count, f"{page}: `{short(cmd)}` prints {count} lines like /{rx}/", f"{n}; printed: {tail}")
        else:
            judge(n > 0, f"{page}: `{short(cmd)}` prints /{rx}/", f"printed: {tail}")
    return ok, out


def command(cmds, program):
    """The block's line that runs PROGRAM (the first)."""
    for c in cmds:
        if re.search(r"(^|/)" + re.escape(program) + r"\b", c.split()[0]) or c.startswith(program + " "):
            return c
    raise KeyError(program)


# The key lines of the examples (docs/guides/dds-lcm.md: "The subscribers print `joystick
# instance=1 status=valid seq=7 ts_us=… x=100 y=-5 z=0 buttons=0x01 memory=0x00 rx_us=…`").
JOYSTICK = r"^joystick instance=[12] status=(valid|error|not_available|stale|offline) seq=\d+ ts_us=\d+ x=-?\d+ y=-?\d+ z=-?\d+ buttons=0x[0-9a-f]{2} memory=0x[0-9a-f]{2} rx_us=\d+$"

# ---- The blocks run here.

state = {}


def dds_lcm_demo(page, cmds):
    """"terminal 1": the demo, in the background while the next block's lines run."""
    (cmd,) = cmds
    state["demo"] = Bg(cmd, "demo-terminal1")
    judge(state["demo"].wait_for(r"publishing every FE on DDS .*partition oegw-demo", 30),
          f"{page}: `{short(cmd)}` publishes (partition oegw-demo)", state["demo"].text()[-400:])


def dds_lcm_examples(page, cmds):
    """"while it runs, these in a second terminal": each line against the demo, in order."""
    expect_run(page, command(cmds, "dds_subscriber"), 0, [JOYSTICK], timeout=15, count=10)
    expect_run(page, command(cmds, "lcm_subscriber"), 0, [JOYSTICK], timeout=15, count=10)
    expect_run(page, command(cmds, "dds_status"), 0,
               [r"^upstream state=[a-z-]+$", r"^subdevice right_grip node=11h state=[a-z-]+ "], timeout=15)
    expect_run(page, command(cmds, "lcm_status"), 0,
               [r"^status seq=\d+ upstream=[a-z-]+ subdevices=5 ", r"^subdevice cluster node=31h state=[a-z-]+ "],
               timeout=15)
    expect_run(page, command(cmds, "dds_command"), 0,
               [r"^sent indicators\.1 indicators=0x0000000000000005 \(on: 1 3\) on oegw/indicators$"], timeout=15)
    expect_run(page, command(cmds, "lcm_command"), 0,
               [r"^sent display\.1 parameters=100,-5,0,0,0,0,0,0,0,0,0,0 on OEGW_DEMO_DISPLAY_1$"], timeout=15)
    demo = state.pop("demo")
    rc = demo.wait(90)
    out = demo.text()
    judge(rc == 0 and "FAILED" not in out, f"{page}: the demo of terminal 1 completes every step beside them (exit 0)",
          f"exit {rc}: " + " | ".join(l for l in out.split("\n") if "FAILED" in l)[:600])
    # The page: `indicators 1 --on 1,3` lights the cluster's lamps 1 and 3 (indicator=10100000).
    last = [l for l in out.split("\n") if re.match(r"^\s+indicators\.1 ", l)]
    judge(bool(last) and re.search(r"indicator=10100000( |$)", last[-1]) is not None,
          f"{page}: dds_command's indicators 1 --on 1,3 lit the demo's lamps 1 and 3",
          last[-1] if last else "no indicators.1 line")


def dds_lcm_watch(page, cmds):
    """"Watch it from two other terminals": the two readers in the background, then the demo."""
    readers = [Bg(c, f"watch{i}") for i, c in enumerate(cmds) if re.search(r"&\s*$", c)]
    demo_line = [c for c in cmds if not re.search(r"&\s*$", c)]
    judge(len(readers) == 2 and len(demo_line) == 1, f"{page}: two readers in the background and the demo",
          f"{cmds}")
    for r in readers:
        judge(r.wait_for(r"^ready$", 10), f"{page}: `{short(r.cmd)}` ready")
    expect_run(page, demo_line[0], 0, [r"ok: every sub-device configured and operational"], timeout=90)
    for r in readers:
        rc = r.wait(40)
        out = r.text()
        judge(rc == 0, f"{page}: `{short(r.cmd)}` exits 0", f"exit {rc}: {out[-300:]}")
        # The page: "joystick.1 valid while it moves, offline when the heartbeat is lost".
        judge(re.search(r"^joystick instance=1 status=valid .* x=-?[1-9]", out, re.M) is not None,
              f"{page}: `{short(r.cmd)}` sees joystick.1 valid and moving")
        valid_then_offline = re.search(r"^joystick instance=1 status=valid [\s\S]*^joystick instance=1 status=offline seq=\d+ ts_us=\d+ x=0 y=0 z=0 ",
                                       out, re.M)
        judge(valid_then_offline is not None, f"{page}: `{short(r.cmd)}` sees joystick.1 offline, neutral, after it moved")


def dds_lcm_logger(page, cmds):
    """"Recording with lcm-logger": the logger (Ctrl-C to stop) records a demo; the decoder reads
    it; the player replays it to a subscriber."""
    logger = Bg(command(cmds, "lcm-logger"), "logger")
    # Recording once it has opened its file (it has joined the group before that).
    log = os.path.join(WORK, "session.lcmlog")
    end = time.monotonic() + 10
    while not os.path.exists(log) and logger.p.poll() is None and time.monotonic() < end:
        time.sleep(0.05)
    judge(os.path.exists(log), f"{page}: `{short(logger.cmd)}` opened session.lcmlog", logger.text()[-300:])
    # The session to record: the demo, as the section before runs it.
    rc, out = run(f"{BUILD}/programs/oegw demo --seconds 1", timeout=90)
    judge(rc == 0, f"{page}: a demo recorded (oegw demo --seconds 1 exits 0)",
          " | ".join(l for l in out.split("\n") if "FAILED" in l))
    logger.interrupt()
    rc = logger.wait(20)
    judge(rc == 0 and os.path.getsize(os.path.join(WORK, "session.lcmlog")) > 0,
          f"{page}: `{short(logger.cmd)}` stopped by Ctrl-C exits 0 with session.lcmlog written",
          f"exit {rc}: {logger.text()[-300:]}")
    ok, out = expect_run(page, command(cmds, "lcm_log_decode"), 0,
                         [r"^joystick instance=1 status=valid ", r"^status seq=\d+ upstream=", r" bad=0$"], timeout=30)
    summary = out.strip().split("\n")[-1]
    m = re.search(r" joystick=(\d+)", summary)
    judge(m is not None and int(m.group(1)) > 0, f"{page}: lcm_log_decode counts the joystick samples", summary)
    # The replay "to the subscribers": one listens while the player plays the session back.
    sub = Bg("build/examples/lcm_subscriber --count 5 --timeout 60 --channel 'OEGW_DEMO_JOYSTICK_[0-9]+'",
             "replayed")
    judge(sub.wait_for(r"^ready$", 10), f"{page}: a subscriber for the replay ready")
    expect_run(page, command(cmds, "lcm-logplayer"), 0, [], timeout=90)
    rc = sub.wait(30)
    judge(rc == 0 and len(re.findall(JOYSTICK, sub.text(), re.M)) == 5,
          f"{page}: the replayed joystick samples reach lcm_subscriber (5 of them)", f"exit {rc}: {sub.text()[-300:]}")


def secure_dds_make(page, cmds):
    """make-dds-security.sh into a temporary folder for /etc/oegw/dds: the files the page lists."""
    (cmd,) = cmds
    expect_run(page, cmd, 0, [], timeout=120)
    want = ["ca.pem", "ca.key", "gateway.pem", "gateway.key", "app.pem", "app.key", "monitor.pem", "monitor.key",
            "governance.p7s", "permissions.p7s"]
    missing = [f for f in want if not os.path.isfile(os.path.join(WORK, "dds", f))]
    judge(not missing, f"{page}: it makes {', '.join(want)}", f"missing: {missing}")


def docs_site(page, cmds):
    """mkdocs build into a temporary folder and the link check; `mkdocs serve` is a server: not run."""
    expect_run(page, command(cmds, "mkdocs build"), 0, [], timeout=180, cwd=SRC)
    judge(os.path.isfile(os.path.join(WORK, "site", "index.html")), f"{page}: mkdocs build wrote the site's index.html")
    expect_run(page, command(cmds, "python3"), 0, [], timeout=60, cwd=SRC)
    print(f"not run: {page}: `{short(command(cmds, 'mkdocs serve'))}` (a server until Ctrl-C; the same site as mkdocs build)")


def man_pages(page, cmds):
    """The manual pages and the completion the build makes (target oegw_man)."""
    for c in cmds:
        if c.startswith("man "):
            expect_run(page, c, 0, [r"oegw"], timeout=30, cwd=SRC)
        elif c.startswith("source "):
            # Then `oegw <Tab><Tab>`: the completion is registered for oegw.
            path = re.sub(r"\s*#.*$", "", c)
            expect_run(page, path + " && complete -p oegw", 0, [r"^complete .* oegw$"], timeout=30, cwd=SRC)


def fenced_blocks(page, lang):
    """The ```LANG blocks of PAGE: (line of the fence, text)."""
    out, fence, text = [], None, []
    with open(os.path.join(SRC, page), encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            if fence is None and line.rstrip() == "```" + lang:
                fence, text = n, []
            elif fence is not None and line.rstrip() == "```":
                out.append((fence, "".join(text)))
                fence = None
            elif fence is not None:
                text.append(line)
    return out


def remote_sdo_recipe(pages):
    """docs/guides/remote-sdo.md's node-canopen recipe for a bound SDO channel: vm_remote extracts
    and runs it against `oegw run` on vcan (a gateway on CAN is needed). Here: there is exactly one,
    node parses it, and it names the channel the page binds (request 690h, response 6B0h, the
    response as the upload's cobIdRx: node-canopen picks the client parameter by it). No page shows
    program code nobody runs: a ```python or ```js block elsewhere fails (python `canopen`, which
    the page once showed, cannot be installed on the build machines: no Debian 12 package)."""
    page = "docs/guides/remote-sdo.md"
    recipes = [(n, t) for n, t in fenced_blocks(page, "js") if "addSdoClientParameter(" in t]
    if not judge(len(recipes) == 1, f"{page}: one node-canopen recipe with addSdoClientParameter",
                 f"{len(recipes)} found"):
        return
    line, text = recipes[0]
    with tempfile.NamedTemporaryFile("w", suffix=".js") as f:
        f.write(text)
        f.flush()
        r = subprocess.run(["node", "--check", f.name], capture_output=True, text=True)
    judge(r.returncode == 0, f"{page}:{line}: the recipe is JavaScript node parses", r.stderr.strip())
    judge("addSdoClientParameter(0x20, 0x690, 0x6b0)" in text and "cobIdRx: 0x6b0" in text,
          f"{page}:{line}: the recipe's SDO client is the page's bound channel 690h/6B0h of node 20h", text)
    for other in pages:
        for lang in ("python", "js"):
            for n, _ in fenced_blocks(other, lang):
                if (other, n) != (page, line):
                    judge(False, f"{other}:{n}: a ```{lang} block no test runs", "run it from a test, or show it as text")


HERE = "here"
# Sections whose every block another test extracts from the page and runs: (page, heading) -> test.
SECTIONS = {
    ("docs/guides/commission.md", "# Commissioning a new cab"): "vm_walkthrough (tests/vm/guest/walkthrough.sh)",
}
# (page, first command) -> ("here", runner) | ("test", NAME) | ("not run", WHY)
BLOCKS = {
    # docs/guides/dds-lcm.md: the examples against the demo, the demo watched, the recording.
    ("docs/guides/dds-lcm.md", "build/programs/oegw demo --seconds 20"): (HERE, dds_lcm_demo),
    ("docs/guides/dds-lcm.md", "build/examples/dds_subscriber --count 10 --timeout 5 --partition oegw-demo"):
        (HERE, dds_lcm_examples),
    ("docs/guides/dds-lcm.md", "build/examples/dds_subscriber --timeout 20 --partition oegw-demo &"): (HERE, dds_lcm_watch),
    ("docs/guides/dds-lcm.md", "lcm-logger --lcm-url='udpm://224.0.0.1:7667?ttl=0' --channel='OEGW_DEMO_.*' -f session.lcmlog"):
        (HERE, dds_lcm_logger),
    ("docs/guides/secure-dds.md", "scripts/make-dds-security.sh --partition oegw --protection encrypt /etc/oegw/dds"):
        (HERE, secure_dds_make),
    ("docs/developer/docs-site.md", "mkdocs build --strict --site-dir build/site"): (HERE, docs_site),
    ("docs/developer/docs-site.md", "man -l build/man/oegw.1.gz"): (HERE, man_pages),
    # docs/guides/simulate.md: its cab file and fault script, run by their own test.
    ("docs/guides/simulate.md", "oegw sim cab.yaml"): ("test", "oegw_sim_guide (tests/tools/sim_guide_test.py)"),
    ("docs/guides/simulate.md", "oegw sim cab.yaml --fast --script faults.txt"):
        ("test", "oegw_sim_guide (tests/tools/sim_guide_test.py)"),
    ("docs/guides/simulate.md", "sudo modprobe vcan"):
        ("not run", "creates vcan interfaces as root; vm_sim_vcan runs the block's `oegw sim cab.yaml --vcan vcan0,vcan1` "
                    "on the VM's vcan0/vcan1 with candump, cansend, oegw status and oegw ctl attached"),
    # Not run: what each needs.
    ("docs/guides/secure-dds.md", "d=/etc/oegw/dds; sec=\"--identity-ca $d/ca.pem --certificate $d/app.pem --private-key $d/app.key \\"):
        ("not run", "a gateway (oegw run, CAN) publishing partition oegw with DDS Security on the cab network's eth1 "
                    "(the same programs with a secured demo: oegw_demo_with_dds_security)"),
    ("docs/guides/install.md", "apt-get install ./build-pkg/oegw_0.1.0_amd64.deb"):
        ("not run", "installs the package as root on a controller (deb_install_test, label deploy, installs it into a Debian root)"),
    ("docs/guides/install.md", "oegw signals mcb402 --find-button-bits -i can1 --node 3"):
        ("not run", "a CAN bus with an MCB-402 and a person pressing its buttons; then an editor, the installed "
                    "/etc/oegw/oegw.yaml (deb_install_test runs `oegw check` on it), systemctl and journalctl"),
    ("docs/guides/install.md", "ip route add 224.0.0.0/4 dev lo"):
        ("test", "vm_abuse (tests/vm/guest/abuse.sh, scenario f: the guest starts without the route, then runs this "
                 "command, and LCM comes up without a restart)"),
    ("docs/guides/build-and-package.md", "./scripts/package.sh"):
        ("not run", "a release build of its own and a package install as root (deb_install_test, label deploy)"),
    ("docs/guides/build-and-package.md", "./scripts/cross-build.sh all"):
        ("not run", "cross toolchains and a cross build of the whole tree per architecture"),
    ("docs/developer/benchmarks.md", "cmake -S . -B build-bench -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo"):
        ("not run", "a second build tree and the benchmarks (figures, never asserted; scripts/test-all.sh runs them)"),
    ("docs/developer/benchmarks.md", "cmake --build build --target oegw_bench_path"):
        ("not run", "a benchmark of about 85 s (figures)"),
    ("docs/developer/benchmarks.md", "ninja -C build-pub -j2 oegw_bench_publish && build-pub/tests/bench/oegw_bench_publish"):
        ("not run", "a second build tree and a benchmark (figures)"),
    ("docs/developer/one-test.md", "nice cmake --build build --target mapping_config_test"):
        ("not run", "build and ctest commands: a test does not run the test runner"),
    ("docs/developer/one-test.md", "nice cmake --build build --target oegw oegw-sim"):
        ("not run", "build and ctest commands: a test does not run the test runner"),
    ("docs/developer/performance.md", "cmake --build build -j2 --target oegw_bench_cab_timing"):
        ("not run", "a benchmark (figures)"),
    ("docs/developer/performance.md", "cmake --build build -j2 --target oegw oegw-sim can_probe can_floor"):
        ("not run", "the VM latency run (qemu, 4-20 minutes)"),
    ("docs/index.md", "./scripts/install-deps.sh && cmake -S . -B build -G Ninja -DOEGW_BUILD_TESTS=OFF && cmake --build build && ./build/programs/oegw demo"):
        ("not run", "installs packages as root and builds the programs (the demo at its end: oegw_demo_screen_*)"),
    ("docs/index.md", "./scripts/test-all.sh"): ("not run", "every test tier: what CI's .ci/run calls"),
    ("README.md", "./scripts/install-deps.sh && cmake -S . -B build -G Ninja -DOEGW_BUILD_TESTS=OFF && cmake --build build && ./build/programs/oegw demo"):
        ("not run", "installs packages as root and builds the programs (the demo at its end: oegw_demo_screen_*)"),
    ("README.md", "./scripts/test-all.sh"): ("not run", "every test tier: what CI's .ci/run calls"),
    ("CONTRIBUTING.md", "cmake --preset dev"):
        ("test", "presets_check (tests/tools/presets_check.py: cmake accepts CMakePresets.json, and each "
                 "test preset selects what the page says on this build tree's test list)"),
    ("CONTRIBUTING.md", "./scripts/install-deps.sh && cmake -S . -B build -G Ninja -DOEGW_BUILD_TESTS=OFF && cmake --build build && ./build/programs/oegw demo"):
        ("not run", "installs packages as root and builds the programs (the demo at its end: oegw_demo_screen_*); "
                    "then every test tier (scripts/test-all.sh, what CI's .ci/run calls)"),
}


def main():
    found = blocks()
    seen = set()
    to_run = []
    for page, line, cmds, heading in found:
        if not cmds:
            continue
        key = (page, first_command(cmds))
        if (page, heading) in SECTIONS:
            print(f"test: {page}:{line}: `{short(key[1])}`: {SECTIONS[(page, heading)]}")
            continue
        seen.add(key)
        how = BLOCKS.get(key)
        if how is None:
            judge(False, f"{page}:{line}: a command block this test does not account for: `{key[1]}`",
                  "add it to BLOCKS in tests/tools/docs_commands_test.py: run it here, name the test that runs it, or say why not")
        elif how[0] == HERE:
            to_run.append((page, line, cmds, how[1]))
        else:
            print(f"{how[0]}: {page}:{line}: `{short(key[1])}`" + (f" ({how[1]})" if how[0] == "not run" else f": {how[1]}"))
    for key in BLOCKS:
        if key not in seen:
            judge(False, f"{key[0]}: no block starts `{key[1]}` any more", "re-classify the page's blocks in BLOCKS")
    missing = [p for p in (f"{BUILD}/programs/oegw", f"{BUILD}/examples/dds_subscriber", f"{BUILD}/man/oegw.1.gz")
               if not os.path.exists(p)]
    remote_sdo_recipe(doc_pages())
    if "--list" in sys.argv[4:]:
        for page, line, cmds, _runner in to_run:
            print(f"here: {page}:{line}: `{short(first_command(cmds))}` ({len(cmds)} commands)")
    elif missing:
        judge(False, "the build's programs", f"missing {missing}: build oegw, the examples and oegw_man first")
    else:
        for page, line, cmds, runner in to_run:
            print(f"== {page}:{line}: {len(cmds)} commands", flush=True)
            runner(page, cmds)
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


def cleanup():
    for b in Bg.started:
        if b.p.poll() is None:
            os.killpg(b.p.pid, signal.SIGKILL)
            b.p.wait()
    shutil.rmtree(WORK, ignore_errors=True)


if __name__ == "__main__":
    atexit.register(cleanup)
    sys.exit(main())
