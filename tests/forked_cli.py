"""`fusionkit` commands forked from one process that has already imported fusionkit, its plugins,
matplotlib and evo, for the executed tutorials: about 90 commands that would each pay its imports (gtsam, the
plugins, evo with scipy, matplotlib: ~1.1 s by -X importtime) before any work; measured, the ten tutorials
took 149 s instead of 204 s (~0.6 s per command).

`serve(socket_path)` imports everything once, then forks a child per connection; the child takes the
caller's stdin/stdout/stderr (passed over the Unix socket), working directory, environment and arguments,
runs the installed entry point's `main` exactly as the console script does, and sends its exit code back.
`write_shim(folder, socket_path)` writes the `fusionkit` the tutorial's shell finds first on its PATH: a
few lines of standard-library Python that forward to the server and exit with the command's code. The
console script itself is run as a subprocess by tests/core/test_cli.py and test_installed_package.py.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import struct
import sys
import traceback
from pathlib import Path

SHIM = """#!{python} -S
import json, os, socket, struct, sys
s = socket.socket(socket.AF_UNIX)
s.connect({socket_path!r})
request = json.dumps({{"argv": sys.argv[1:], "cwd": os.getcwd(), "env": dict(os.environ)}}).encode()
socket.send_fds(s, [struct.pack("!Q", len(request))], [0, 1, 2])
s.sendall(request)
reply = s.recv(16)
sys.exit(int(reply) if reply else "fusionkit (forked): the command's process died without an exit code")
"""


def write_shim(folder: Path, socket_path: str) -> None:
    """`folder/fusionkit`, forwarding its arguments, folders, environment and standard streams to the server."""
    shim = folder / "fusionkit"
    shim.write_text(SHIM.format(python=sys.executable, socket_path=socket_path))
    shim.chmod(0o755)


def _receive(conn: socket.socket) -> tuple[dict, list[int]]:
    header, fds, _, _ = socket.recv_fds(conn, 8, 3)
    size, = struct.unpack("!Q", header)
    data = b""
    while len(data) < size:
        data += conn.recv(size - len(data))
    return json.loads(data), fds


def _run_command(conn: socket.socket) -> None:
    """In the forked child: become the caller's process (streams, folder, environment) and run main."""
    signal.signal(signal.SIGCHLD, signal.SIG_DFL)
    request, fds = _receive(conn)
    for target, fd in enumerate(fds):
        os.dup2(fd, target)
        os.close(fd)
    os.chdir(request["cwd"])
    os.environ.clear()
    os.environ.update(request["env"])
    sys.argv = ["fusionkit", *request["argv"]]
    from fusionkit.cli.main import main
    try:
        code = main()
    except SystemExit as exc:  # argparse's --help and usage errors, as in the console script
        code = exc.code
    except BaseException:  # what would end the console script with a traceback (e.g. under --debug)
        traceback.print_exc()
        code = 1
    if isinstance(code, str):
        print(code, file=sys.stderr)
        code = 1
    sys.stdout.flush()
    sys.stderr.flush()
    conn.sendall(str(code or 0).encode())


def serve(socket_path: str) -> None:
    import importlib
    for module in ("matplotlib.pyplot", "evo.core.metrics", "fusionkit.cli.main"):  # what `run` imports
        importlib.import_module(module)
    from fusionkit.plugins import registry
    registry()
    signal.signal(signal.SIGCHLD, signal.SIG_IGN)  # children are reaped by the kernel
    listener = socket.socket(socket.AF_UNIX)
    listener.bind(socket_path)
    listener.listen(8)
    print("ready", flush=True)
    while True:
        conn, _ = listener.accept()
        if os.fork() == 0:
            listener.close()
            try:
                _run_command(conn)
            finally:
                os._exit(0)
        conn.close()


if __name__ == "__main__":
    serve(sys.argv[1])
