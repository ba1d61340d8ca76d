#!/usr/bin/env python3
"""Parses and checks bot-procman (.pmd) configurations.

The grammar is libbot2's sheriff configuration (bot2-procman's
sheriff_config.py), reimplemented here because bot-procman is not in Debian:

    file    := { cmd | group | script }
    group   := "group" STRING "{" { cmd | group } "}"
    cmd     := "cmd" [STRING] "{" { ATTR "=" VALUE ";" } "}"
               ATTR: exec, host, auto_respawn, group (strings),
                     stop_signal, stop_time_allowed (integers)
    script  := "script" STRING "{" { action } "}"
    action  := ("start" | "stop" | "restart")
                   ("everything" | "cmd" STRING | "group" STRING)
                   [ "wait" ("running" | "stopped") ] ";"
             | "wait" "ms" INTEGER ";"
             | "wait" ("cmd" | "group") STRING "status" ("running" | "stopped") ";"
             | "run_script" STRING ";"
    STRING  := '"' ... '"' on one line, with \\ escapes;  '#' comments to the end of a line.

Beyond the grammar it checks what the sheriff would only find out at run
time: every command has an exec and a host, names are unique, every script
names commands, groups and scripts that exist, and commands on several hosts
share one LCM URL with ttl >= 1. Then every exec string is run as the deputy
would run it (shell-style words, leading VAR=value assignments, $VAR and
${VAR} substituted), with the first word replaced by BUILD/bin/NAME and
--check appended: each roomfix process validates its flags and site file
with --check and exits without running.

    pmd_check.py --build BUILD --source SOURCE [FILE.pmd ...]
        checks FILEs (default: SOURCE/config/procman/*.pmd and
        SOURCE/config/procman/installed/*.pmd); exit 1 on any error. Paths
        under /usr/share/roomfix/ (the package's data) are read from SOURCE/.
        A file in installed/ must also be the twin of the source-tree file of
        its name: the same commands, attributes and scripts, its paths under
        /usr/share/roomfix/ where the other has ${ROOMFIX_HOME}/.
    pmd_check.py --build BUILD --source SOURCE --expect-failures DIR
        every DIR/*.pmd starts with '# expect: TEXT': the check must fail on
        it with an error containing TEXT
    pmd_check.py --list FILE.pmd
        parses FILE and prints its commands, groups and scripts (no build needed)
"""

import argparse
import glob
import os
import re
import shlex
import subprocess
import sys
import tempfile

# Where the package puts roomfix's data (GNUInstallDirs: DATADIR/roomfix),
# laid out as the source tree's config/: the configurations for installed
# hosts (config/procman/installed/) name files there, and the check reads
# them from the source tree instead.
INSTALLED_SHARE = "/usr/share/roomfix"

# The variables the shipped configurations may use, and what the check
# substitutes for them (docs/procman.md says what a deputy's environment sets).
KNOWN_VARIABLES = ("ROOMFIX_HOME", "ROOMFIX_LOG_DIR", "ROOMFIX_RUN_DIR")

DEFAULT_LCM_URL = "udpm://239.255.76.67:7667?ttl=0"


class PmdError(Exception):
    """A problem in a .pmd file, with its place when it has one."""

    def __init__(self, path, line, msg):
        super().__init__(msg)
        self.path = path
        self.line = line
        self.msg = msg

    def __str__(self):
        if self.line:
            return "%s:%d: %s" % (self.path, self.line, self.msg)
        return "%s: %s" % (self.path, self.msg)


# ---------------------------------------------------------------- tokenizer

IDENT, STRING, INTEGER, PUNCT, EOF = "identifier", "string", "integer", "punctuation", "end of file"


class Token:
    def __init__(self, kind, value, line):
        self.kind = kind
        self.value = value
        self.line = line

    def describe(self):
        if self.kind == EOF:
            return "end of file"
        if self.kind == STRING:
            return 'string "%s"' % self.value
        return "'%s'" % self.value


def tokenize(text, path):
    tokens = []
    i, line, n = 0, 1, len(text)
    escapes = {"n": "\n", "r": "\r", "t": "\t"}
    while i < n:
        c = text[i]
        if c == "\n":
            line += 1
            i += 1
        elif c.isspace():
            i += 1
        elif c == "#":
            while i < n and text[i] != "\n":
                i += 1
        elif c in "={};":
            tokens.append(Token(PUNCT, c, line))
            i += 1
        elif c == '"':
            start_line = line
            i += 1
            chars = []
            while True:
                if i >= n or text[i] == "\n":
                    raise PmdError(path, start_line, "unterminated string constant")
                if text[i] == "\\" and i + 1 < n and text[i + 1] != "\n":
                    chars.append(escapes.get(text[i + 1], text[i + 1]))
                    i += 2
                elif text[i] == '"':
                    i += 1
                    break
                else:
                    chars.append(text[i])
                    i += 1
            tokens.append(Token(STRING, "".join(chars), start_line))
        elif c.isalpha() or c == "_":
            j = i + 1
            while j < n and (text[j].isalnum() or text[j] in "_-"):
                j += 1
            tokens.append(Token(IDENT, text[i:j], line))
            i = j
        elif c.isdigit():
            j = i + 1
            while j < n and text[j].isdigit():
                j += 1
            tokens.append(Token(INTEGER, int(text[i:j]), line))
            i = j
        else:
            raise PmdError(path, line, "invalid character %r" % c)
    tokens.append(Token(EOF, "", line))
    return tokens


# ------------------------------------------------------------------- parser


class Command:
    def __init__(self, name, group, line):
        self.name = name
        self.group = group  # "a/b" path of nested groups; "" at the top
        self.line = line
        self.attributes = {}

    @property
    def exec_str(self):
        return self.attributes.get("exec")

    @property
    def host(self):
        return self.attributes.get("host")


class Action:
    def __init__(self, verb, target_type, target, wait, line):
        self.verb = verb  # start, stop, restart, wait_ms, wait_status, run_script
        self.target_type = target_type  # everything, cmd, group, script, ms
        self.target = target
        self.wait = wait
        self.line = line

    def __str__(self):
        if self.verb == "wait_ms":
            return "wait ms %d" % self.target
        if self.verb == "wait_status":
            return 'wait %s "%s" status "%s"' % (self.target_type, self.target, self.wait)
        if self.verb == "run_script":
            return 'run_script "%s"' % self.target
        what = "everything" if self.target_type == "everything" else '%s "%s"' % (
            self.target_type, self.target)
        return "%s %s%s" % (self.verb, what, ' wait "%s"' % self.wait if self.wait else "")


class Config:
    def __init__(self, path):
        self.path = path
        self.commands = []
        self.groups = {}  # "a/b" -> line of its first opening
        self.scripts = {}  # name -> (line, [Action])


CMD_ATTRIBUTES = {"exec": STRING, "host": STRING, "auto_respawn": STRING, "group": STRING,
                  "stop_signal": INTEGER, "stop_time_allowed": INTEGER}


class Parser:
    def __init__(self, text, path):
        self.path = path
        self.tokens = tokenize(text, path)
        self.pos = 0
        self.config = Config(path)

    def peek(self):
        return self.tokens[self.pos]

    def next(self):
        tok = self.tokens[self.pos]
        if tok.kind != EOF:
            self.pos += 1
        return tok

    def fail(self, tok, msg):
        raise PmdError(self.path, tok.line, msg)

    def expect(self, kind, value=None, what=None, opened=None):
        tok = self.next()
        if tok.kind == kind and (value is None or tok.value == value):
            return tok
        if tok.kind == EOF and opened is not None:
            self.fail(tok, "unterminated %s (opened at line %d): end of file before '}'"
                      % opened)
        self.fail(tok, "expected %s, found %s" % (what or repr(value) or kind, tok.describe()))

    def eat(self, kind, value=None):
        tok = self.peek()
        if tok.kind == kind and (value is None or tok.value == value):
            self.pos += 1
            return tok
        return None

    def parse(self):
        while self.peek().kind != EOF:
            tok = self.expect(IDENT, what="'cmd', 'group' or 'script'")
            if tok.value == "cmd":
                self.parse_command("", tok)
            elif tok.value == "group":
                self.parse_group("", tok)
            elif tok.value == "script":
                self.parse_script(tok)
            else:
                self.fail(tok, "expected 'cmd', 'group' or 'script', found '%s'" % tok.value)
        return self.config

    def parse_command(self, group, cmd_tok):
        name_tok = self.eat(STRING)
        name = name_tok.value if name_tok else ""
        if "/" in name:
            self.fail(name_tok, "'/' is not allowed in a command name")
        what = ('cmd "%s"' % name if name else "cmd", cmd_tok.line)
        self.expect(PUNCT, "{", "'{' after cmd")
        cmd = Command(name, group, cmd_tok.line)
        while not self.eat(PUNCT, "}"):
            tok = self.peek()
            if tok.kind == EOF:
                self.fail(tok, "unterminated %s block (opened at line %d): end of file before '}'"
                          % what)
            attr = self.expect(IDENT, what="a command attribute or '}'")
            if attr.value not in CMD_ATTRIBUTES:
                self.fail(attr, "unknown command attribute '%s' (expected one of %s)"
                          % (attr.value, ", ".join(sorted(CMD_ATTRIBUTES))))
            if attr.value in cmd.attributes:
                self.fail(attr, "attribute '%s' given twice" % attr.value)
            self.expect(PUNCT, "=", "'=' after %s" % attr.value)
            kind = CMD_ATTRIBUTES[attr.value]
            val = self.expect(kind, what="a %s for %s" % (kind, attr.value))
            if kind == INTEGER and val.value < 1:
                self.fail(val, "%s must be at least 1" % attr.value)
            self.expect(PUNCT, ";", "';' after the value of %s" % attr.value)
            cmd.attributes[attr.value] = val.value
        if "group" in cmd.attributes and not group:
            cmd.group = cmd.attributes["group"].strip("/")
            self.config.groups.setdefault(cmd.group, cmd_tok.line)
        if not cmd.exec_str:
            self.fail(cmd_tok, "%s has no exec" % what[0])
        if not cmd.host:
            self.fail(cmd_tok, "%s has no host (the deputy that runs it)" % what[0])
        respawn = cmd.attributes.get("auto_respawn")
        if respawn is not None and respawn not in ("true", "false"):
            self.fail(cmd_tok, '%s: auto_respawn must be "true" or "false", not "%s"'
                      % (what[0], respawn))
        self.config.commands.append(cmd)

    def parse_group(self, parent, group_tok):
        name_tok = self.expect(STRING, what="a group name string")
        if "/" in name_tok.value:
            self.fail(name_tok, "'/' is not allowed in a group name")
        if not name_tok.value.strip():
            self.fail(name_tok, "empty group name")
        path = parent + "/" + name_tok.value if parent else name_tok.value
        self.config.groups.setdefault(path, group_tok.line)
        self.expect(PUNCT, "{", "'{' after the group name")
        while not self.eat(PUNCT, "}"):
            tok = self.next()
            if tok.kind == EOF:
                self.fail(tok, 'unterminated group "%s" block (opened at line %d): end of file '
                          "before '}'" % (path, group_tok.line))
            if tok.kind == IDENT and tok.value == "cmd":
                self.parse_command(path, tok)
            elif tok.kind == IDENT and tok.value == "group":
                self.parse_group(path, tok)
            else:
                self.fail(tok, "expected 'cmd', 'group' or '}' in group \"%s\", found %s"
                          % (path, tok.describe()))

    def parse_script(self, script_tok):
        name = self.expect(STRING, what="a script name string").value
        if name in self.config.scripts:
            self.fail(script_tok, 'script "%s" defined twice' % name)
        self.expect(PUNCT, "{", "'{' after the script name")
        actions = []
        while not self.eat(PUNCT, "}"):
            tok = self.next()
            if tok.kind == EOF:
                self.fail(tok, 'unterminated script "%s" block (opened at line %d): end of file '
                          "before '}'" % (name, script_tok.line))
            if tok.kind != IDENT:
                self.fail(tok, "expected a script action, found %s" % tok.describe())
            if tok.value in ("start", "stop", "restart"):
                kind = self.expect(IDENT, what="'everything', 'cmd' or 'group'")
                if kind.value not in ("everything", "cmd", "group"):
                    self.fail(kind, "expected 'everything', 'cmd' or 'group' after %s" % tok.value)
                target = None
                if kind.value != "everything":
                    target = self.expect(STRING, what="a %s name string" % kind.value).value
                wait = None
                if self.eat(IDENT, "wait"):
                    wait = self.expect(STRING, what='"running" or "stopped"')
                    if wait.value not in ("running", "stopped"):
                        self.fail(wait, 'expected "running" or "stopped" after wait')
                    wait = wait.value
                self.expect(PUNCT, ";", "';' or 'wait'")
                actions.append(Action(tok.value, kind.value, target, wait, tok.line))
            elif tok.value == "wait":
                kind = self.expect(IDENT, what="'ms', 'cmd' or 'group' after wait")
                if kind.value == "ms":
                    ms = self.expect(INTEGER, what="milliseconds after 'wait ms'")
                    self.expect(PUNCT, ";", "';'")
                    actions.append(Action("wait_ms", "ms", ms.value, None, tok.line))
                elif kind.value in ("cmd", "group"):
                    target = self.expect(STRING, what="a %s name string" % kind.value).value
                    self.expect(IDENT, "status", "'status'")
                    status = self.expect(STRING, what='"running" or "stopped"')
                    if status.value not in ("running", "stopped"):
                        self.fail(status, 'expected "running" or "stopped" after status')
                    self.expect(PUNCT, ";", "';'")
                    actions.append(Action("wait_status", kind.value, target, status.value,
                                          tok.line))
                else:
                    self.fail(kind, "expected 'ms', 'cmd' or 'group' after wait")
            elif tok.value == "run_script":
                target = self.expect(STRING, what="a script name string").value
                self.expect(PUNCT, ";", "';'")
                actions.append(Action("run_script", "script", target, None, tok.line))
            else:
                self.fail(tok, "unknown script action '%s' (expected start, stop, restart, wait "
                          "or run_script)" % tok.value)
        self.config.scripts[name] = (script_tok.line, actions)


def parse_file(path):
    with open(path, encoding="utf-8") as f:
        return Parser(f.read(), path).parse()


# --------------------------------------------------------- semantic checks


def check_references(config):
    """Names unique; scripts name existing commands, groups and scripts."""
    errors = []
    names = {}
    for cmd in config.commands:
        if not cmd.name:
            continue
        if cmd.name in names:
            errors.append(PmdError(config.path, cmd.line, 'command "%s" defined twice (first at '
                                   "line %d)" % (cmd.name, names[cmd.name])))
        names.setdefault(cmd.name, cmd.line)
    for script, (_, actions) in config.scripts.items():
        for a in actions:
            if a.target_type == "cmd" and a.target not in names:
                errors.append(PmdError(config.path, a.line, 'script "%s" names unknown command '
                                       '"%s"' % (script, a.target)))
            elif a.target_type == "group" and a.target.strip("/") not in config.groups:
                errors.append(PmdError(config.path, a.line, 'script "%s" names unknown group '
                                       '"%s"' % (script, a.target)))
            elif a.target_type == "script":
                if a.target not in config.scripts:
                    errors.append(PmdError(config.path, a.line, 'script "%s" runs unknown script '
                                           '"%s"' % (script, a.target)))
                elif a.target == script:
                    errors.append(PmdError(config.path, a.line, 'script "%s" runs itself'
                                           % script))
    return errors


def substitute(word, variables, path, line, cmd_name):
    """The deputy's $VAR / ${VAR} expansion, restricted to known variables."""
    def repl(m):
        name = m.group(1) or m.group(2)
        if name not in variables:
            raise PmdError(path, line, 'command "%s" uses $%s, which is none of %s'
                           % (cmd_name, name, ", ".join(KNOWN_VARIABLES)))
        return variables[name]
    return re.sub(r"\$\{([A-Za-z_][A-Za-z0-9_]*)\}|\$([A-Za-z_][A-Za-z0-9_]*)", repl, word)


def split_exec(cmd, variables, path):
    """(environment assignments, argv) as the deputy builds them."""
    try:
        words = shlex.split(cmd.exec_str)
    except ValueError as e:
        raise PmdError(path, cmd.line, 'command "%s": exec is not a shell word list: %s'
                       % (cmd.name, e))
    env = {}
    while words and re.match(r"^[A-Za-z_][A-Za-z0-9_]*=", words[0]):
        key, value = words.pop(0).split("=", 1)
        env[key] = value
    if not words:
        raise PmdError(path, cmd.line, 'command "%s": exec names no program' % cmd.name)
    argv = [substitute(w, variables, path, cmd.line, cmd.name) for w in words]
    share = INSTALLED_SHARE + "/"
    argv = [variables["ROOMFIX_HOME"] + "/" + w[len(share):] if w.startswith(share) else w
            for w in argv]
    return env, argv


def lcm_url_of(argv):
    for i, w in enumerate(argv):
        if w == "--lcm-url" and i + 1 < len(argv):
            return argv[i + 1]
        if w.startswith("--lcm-url="):
            return w.split("=", 1)[1]
    return DEFAULT_LCM_URL


def check_file(path, build, variables, out):
    """Checks one file; prints a line per command; returns the list of errors."""
    try:
        config = parse_file(path)
    except PmdError as e:
        return [e]
    except OSError as e:
        return [PmdError(path, 0, "cannot read: %s" % e.strerror)]
    errors = check_references(config)
    if not config.commands:
        errors.append(PmdError(path, 0, "no commands"))
    hosts = sorted({c.host for c in config.commands})
    urls = {}
    bin_dir = os.path.join(build, "bin")
    for cmd in config.commands:
        label = 'cmd "%s" on %s' % (cmd.name, cmd.host)
        try:
            env, argv = split_exec(cmd, variables, path)
        except PmdError as e:
            errors.append(e)
            continue
        program = argv[0]
        if "/" in program:
            errors.append(PmdError(path, cmd.line, '%s: exec names "%s" by path; name the binary '
                                   "and put its folder on the deputy's PATH" % (label, program)))
            continue
        binary = os.path.join(bin_dir, program)
        # No exemptions: every program must be built and accept its flags.
        if not os.access(binary, os.X_OK):
            errors.append(PmdError(path, cmd.line, '%s: unknown binary "%s" (no %s)'
                                   % (label, program, binary)))
            continue
        urls.setdefault(lcm_url_of(argv[1:]), []).append(cmd.name)
        run_env = dict(os.environ)
        run_env.update(env)
        # --check never opens a window; a window-mode viewer still wants DISPLAY.
        run_env.setdefault("DISPLAY", ":0")
        try:
            proc = subprocess.run([binary] + argv[1:] + ["--check"], env=run_env,
                                  stdin=subprocess.DEVNULL, capture_output=True, text=True,
                                  timeout=30)
        except subprocess.TimeoutExpired:
            errors.append(PmdError(path, cmd.line, "%s: %s --check did not finish in 30 s"
                                   % (label, program)))
            continue
        said = (proc.stderr.strip() or proc.stdout.strip()).splitlines()
        first = said[-1] if said else "(nothing)"
        if proc.returncode != 0:
            # CLI11 prints the offending flag first, then a hint line.
            first = said[0] if said else "(nothing)"
            errors.append(PmdError(path, cmd.line, "%s: %s rejects its command line: %s"
                                   % (label, program, first)))
            continue
        if "ok" not in proc.stdout:
            errors.append(PmdError(path, cmd.line, "%s: %s --check printed '%s', not ok"
                                   % (label, program, proc.stdout.strip())))
            continue
        out.write("ok: %s: %s: %s\n" % (os.path.basename(path), label,
                                        proc.stdout.strip().splitlines()[-1]))
    if len(urls) > 1:
        errors.append(PmdError(path, 0, "commands use different LCM URLs and cannot hear each "
                               "other: %s" % "; ".join("%s: %s" % (u, ", ".join(n))
                                                       for u, n in sorted(urls.items()))))
    if len(hosts) > 1:
        for url, names in sorted(urls.items()):
            m = re.search(r"[?&]ttl=(\d+)", url)
            if url.startswith("udpm://") and (m is None or int(m.group(1)) < 1):
                errors.append(PmdError(path, 0, "commands on several hosts (%s) need an LCM URL "
                                       "with ttl=1, not %s (%s)"
                                       % (", ".join(hosts), url, ", ".join(names))))
    if not errors:
        out.write("ok: %s: %d commands on %s, %d groups, scripts: %s\n"
                  % (os.path.basename(path), len(config.commands), ", ".join(hosts),
                     len(config.groups), ", ".join(sorted(config.scripts)) or "none"))
    return errors


def twin_errors(installed_path, source_path):
    """An installed-host file must differ from its source-tree twin only in
    where the data is: /usr/share/roomfix/ for ${ROOMFIX_HOME}/."""
    try:
        ours = parse_file(installed_path)
        theirs = parse_file(source_path)
    except PmdError as e:
        return [e]
    except OSError as e:
        return [PmdError(installed_path, 0, "no source-tree twin: %s: %s"
                         % (source_path, e.strerror))]

    def commands(config, from_share):
        result = {}
        for c in config.commands:
            attributes = dict(c.attributes)
            attributes.pop("nickname", None)
            text = c.exec_str
            if from_share:
                text = text.replace(INSTALLED_SHARE + "/", "${ROOMFIX_HOME}/")
            result[c.name] = (c.host, c.group, text, sorted(
                (k, v) for k, v in attributes.items() if k != "exec"))
        return result

    def scripts(config):
        return {name: [str(a) for a in actions] for name, (_, actions) in config.scripts.items()}

    errors = []
    a, b = commands(ours, True), commands(theirs, False)
    for name in sorted(set(a) | set(b)):
        if a.get(name) != b.get(name):
            line = next((c.line for c in ours.commands if c.name == name), 0)
            errors.append(PmdError(installed_path, line, 'command "%s" differs from its twin in %s '
                                   "(other than /usr/share/roomfix/ for ${ROOMFIX_HOME}/)"
                                   % (name, source_path)))
    if scripts(ours) != scripts(theirs):
        errors.append(PmdError(installed_path, 0, "scripts differ from its twin in %s"
                               % source_path))
    return errors


def list_config(path):
    config = parse_file(path)
    for cmd in config.commands:
        print('cmd "%s" host=%s group=%s auto_respawn=%s\n    exec: %s'
              % (cmd.name, cmd.host, cmd.group or "-", cmd.attributes.get("auto_respawn", "false"),
                 cmd.exec_str))
    for name, (_, actions) in sorted(config.scripts.items()):
        print('script "%s":' % name)
        for a in actions:
            print("    %s;" % a)
    return check_references(config)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", help="build folder holding bin/")
    ap.add_argument("--source", help="source folder (substituted for $ROOMFIX_HOME)")
    ap.add_argument("--expect-failures", metavar="DIR",
                    help="every DIR/*.pmd must fail with its '# expect: TEXT'")
    ap.add_argument("--list", metavar="FILE", help="print FILE's commands and scripts")
    ap.add_argument("files", nargs="*")
    args = ap.parse_args()

    if args.list:
        try:
            errors = list_config(args.list)
        except PmdError as e:
            errors = [e]
        for e in errors:
            print("error: %s" % e, file=sys.stderr)
        return 1 if errors else 0
    if not args.build or not args.source:
        ap.error("--build and --source are needed to check")

    args.build = os.path.abspath(args.build)
    scratch = tempfile.mkdtemp(prefix="pmd_check.")
    variables = {"ROOMFIX_HOME": os.path.abspath(args.source),
                 "ROOMFIX_LOG_DIR": scratch, "ROOMFIX_RUN_DIR": scratch}
    failures = 0
    try:
        if args.expect_failures:
            files = sorted(glob.glob(os.path.join(args.expect_failures, "*.pmd")))
            if not files:
                print("FAIL: no .pmd files in %s" % args.expect_failures)
                return 1
            for path in files:
                with open(path, encoding="utf-8") as f:
                    first = f.readline()
                m = re.match(r"#\s*expect:\s*(.+)", first)
                if not m:
                    print("FAIL: %s: first line is not '# expect: TEXT'" % path)
                    failures += 1
                    continue
                expected = m.group(1).strip()
                sink = open(os.devnull, "w")
                errors = check_file(path, args.build, variables, sink)
                sink.close()
                texts = [str(e) for e in errors]
                if not errors:
                    print("FAIL: %s: accepted, expected '%s'" % (path, expected))
                    failures += 1
                elif not any(expected in t and t.startswith(path) for t in texts):
                    print("FAIL: %s: expected '%s', got:\n  %s" % (path, expected,
                                                                    "\n  ".join(texts)))
                    failures += 1
                else:
                    print("ok: rejected: %s" % next(t for t in texts if expected in t))
            return 1 if failures else 0

        procman_dir = os.path.join(args.source, "config", "procman")
        files = args.files or (sorted(glob.glob(os.path.join(procman_dir, "*.pmd"))) +
                               sorted(glob.glob(os.path.join(procman_dir, "installed", "*.pmd"))))
        if not files:
            print("FAIL: no .pmd files to check")
            return 1
        for path in files:
            errors = check_file(path, args.build, variables, sys.stdout)
            if os.path.basename(os.path.dirname(os.path.abspath(path))) == "installed":
                twin = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(path))),
                                    os.path.basename(path))
                errors += twin_errors(path, twin)
            for e in errors:
                print("FAIL: %s" % e)
                failures += 1
        sys.stdout.flush()
        return 1 if failures else 0
    finally:
        for name in os.listdir(scratch):
            os.remove(os.path.join(scratch, name))
        os.rmdir(scratch)


if __name__ == "__main__":
    sys.exit(main())
