"""The processes below a process, read from /proc (Linux): for tests that stop, pause or kill
the children a command starts."""
import os


def table() -> dict[int, tuple[int, str]]:
    """pid -> (parent pid, command line) of every process."""
    out = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    parent = int(f.read().rsplit(")", 1)[1].split()[1])
                with open(f"/proc/{entry}/cmdline", "rb") as f:
                    command = f.read().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            out[int(entry)] = (parent, command)
    return out


def children(pid: int, marker: str) -> list[int]:
    """The children of ``pid`` whose command line holds ``marker``."""
    return [p for p, (parent, command) in table().items() if parent == pid and marker in command]


def descendants(root: int) -> dict[int, str]:
    """pid -> command line of every process below ``root``."""
    procs, out, frontier = table(), {}, [root]
    while frontier:
        pid = frontier.pop()
        for child, (parent, command) in procs.items():
            if parent == pid and child not in out:
                out[child] = command
                frontier.append(child)
    return out


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie does not)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False
