"""A ``kinecal`` for tests/test_docs_walkthroughs.py that does not pay Python's start-up per
command: a server process imports kinecal and every command module once, then forks a child
per command; the ``kinecal`` the shell finds on the PATH is a small client that hands the
child its arguments, working folder, environment and its stdin, stdout and stderr (the file
descriptors themselves, so a terminal, a pipe or a redirection is what the command sees) and
exits with the child's status.

Each command still runs in a process of its own, from the state right after the imports:
nothing carries over from one command to the next. Set ``KINECAL_DOCS_PLAIN=1`` to run every
command in a fresh interpreter instead (what a user's shell does; slower).

Run as ``python docs_server.py SOCKET`` (the server); `client_script` writes the client.
"""

from __future__ import annotations

import json
import os
import socket
import struct
import sys


def client_script(python: str, address: str, kind: str = "kinecal") -> str:
    """The source of a client (runs with ``python -SE``: no site imports): ``kinecal`` runs
    the command line, ``python`` a script (``client SCRIPT``, as ``python SCRIPT``)."""
    return f"""#!{python} -SE
import json, os, socket, struct, sys
s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
s.connect({address!r})
data = json.dumps({{"kind": {kind!r}, "argv": sys.argv[1:], "cwd": os.getcwd(),
                   "env": dict(os.environ)}}).encode()
socket.send_fds(s, [struct.pack("!I", len(data)) + data], [0, 1, 2])
got = b""
while len(got) < 4:
    chunk = s.recv(4 - len(got))
    if not chunk:
        sys.stderr.write("kinecal (docs test server): the command died without a status\\n")
        os._exit(70)
    got += chunk
os._exit(struct.unpack("!i", got)[0])
"""


def _receive(conn: socket.socket) -> tuple[dict, list[int]]:
    msg, fds, _, _ = socket.recv_fds(conn, 1 << 16, 3)
    size = struct.unpack("!I", msg[:4])[0]
    data = msg[4:]
    while len(data) < size:
        chunk = conn.recv(size - len(data))
        if not chunk:
            raise EOFError("client went away")
        data += chunk
    return json.loads(data), fds


def _child(conn: socket.socket) -> None:
    """Run one command with the client's arguments, folder, environment and streams."""
    code = 70
    try:
        request, fds = _receive(conn)
        for target, fd in enumerate(fds):
            os.dup2(fd, target)
            os.close(fd)
        os.chdir(request["cwd"])
        os.environ.clear()
        os.environ.update(request["env"])
        try:
            code = _run(request["kind"], list(request["argv"]))
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except OSError:
                pass
        try:
            conn.sendall(struct.pack("!i", int(code)))
        finally:
            os._exit(int(code) & 0xFF)


def _run(kind: str, argv: list[str]) -> int:
    if kind == "python":  # python SCRIPT ARGS...: the script as __main__
        import runpy
        import traceback

        sys.argv = list(argv)
        sys.path.insert(0, os.path.dirname(os.path.abspath(argv[0])))
        try:
            runpy.run_path(argv[0], run_name="__main__")
        except SystemExit:
            raise
        except BaseException:
            traceback.print_exc()
            return 1
        return 0
    from kinecal.cli import main

    return main(argv)


def serve(address: str) -> None:
    """Import kinecal and its commands, then fork a child per connection."""
    import signal

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot
    import scipy.optimize  # noqa: F401

    import kinecal.calibration.serial.api
    import kinecal.cli as cli
    import kinecal.io.measurements
    import kinecal.report.html  # noqa: F401

    cli._load_commands()

    def reap(*_) -> None:  # waited for, so that their CPU time counts as the server's
        try:
            while os.waitpid(-1, os.WNOHANG)[0] > 0:
                pass
        except ChildProcessError:
            pass

    signal.signal(signal.SIGCHLD, reap)
    server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    server.bind(address + ".tmp")
    server.listen(64)
    os.rename(address + ".tmp", address)  # ready: the clients may connect
    while True:
        try:
            conn, _ = server.accept()
        except InterruptedError:  # a child ended during accept
            continue
        if os.fork() == 0:
            server.close()
            signal.signal(signal.SIGCHLD, signal.SIG_DFL)
            _child(conn)
        conn.close()


if __name__ == "__main__":
    serve(sys.argv[1])
