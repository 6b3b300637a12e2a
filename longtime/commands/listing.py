"""``longtime list``: the problems, the schemes, their capabilities and the broken plugins."""
from __future__ import annotations

from longtime.core import jsontext, registry
from longtime.measure import stability


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("list", help="problems, schemes, their capabilities and broken plugins")
    p.add_argument("--format", choices=["table", "json"], default="table")
    p.add_argument("--stability", action="store_true",
                   help="measure each scheme's imaginary-axis stability interval where it is not "
                        "cached (compiles every step kernel: about a minute the first time)")
    p.add_argument("--full", action="store_true",
                   help="each scheme's interval that is not measured with its reason (by default counted in "
                        "one line)")
    p.set_defaults(func=cmd_list)


def _why_not(name: str, error: str) -> str:
    """The kind of reason an interval is not measured: 'an external integrator', 'needs
    lorentz' (a scheme's own name and the problem's left out)."""
    import re

    why = re.sub(rf"^{re.escape(name)}\s+(is\s+)?", "", error)
    return re.split(r": |, which", why)[0]


def cmd_list(args) -> int:
    problems, schemes = registry.problems(), registry.integrators()
    data = {
        "problems": [{"name": n, "summary": c.summary, "capabilities": sorted(c.capabilities()),
                      "parameters": {k: p.default for k, p in c.parameters.items()}}
                     for n, c in problems.items()],
        "integrators": [{"name": n, "summary": c.summary, "kind": c.kind, "order": c.order,
                         "symplectic": c.symplectic, "requires": sorted(c.requires), "needs": c.needs,
                         "parameters": {k: p.default for k, p in c.parameters.items()},
                         "imaginary_interval": stability.intervals(n, compute=args.stability),
                         "notice": c.notice}
                        for n, c in schemes.items()],
        "broken": [vars(b) for b in registry.broken()],
    }
    if args.format == "json":
        print(jsontext.dumps(data))
        return 0
    print("problems:")
    for p in data["problems"]:
        print(f"  {p['name']:24s} {p['summary']}\n  {'':24s} provides: {', '.join(p['capabilities'])}")
    print("integrators:")
    unmeasured: dict[str, list[str]] = {}  # why an interval is not measured -> the schemes
    for i in data["integrators"]:
        needs = ", ".join(i["requires"] + ([i["needs"]] if i["needs"] else [])) or "-"
        sym = " symplectic" if i["symplectic"] else ""
        print(f"  {i['name']:24s} {i['kind']:8s} order {i['order']}{sym}; needs {needs}\n"
              f"  {'':24s} {i['summary']}; parameters: {', '.join(i['parameters']) or '-'}")
        if i["notice"]:
            print(f"  {'':24s} notice: {i['notice']}")
        intervals = i["imaginary_interval"]
        if intervals and not args.full and all("error" in r for r in intervals.values()):
            for r in intervals.values():
                unmeasured.setdefault(_why_not(i["name"], r["error"]), []).append(i["name"])
        elif intervals:
            print(f"  {'':24s} stable on the imaginary axis (|R(iy)| <= 1), y in: " + "; ".join(
                f"{label} {stability.format_interval(r)}".strip() for label, r in intervals.items()))
    if unmeasured:
        total = len({n for names in unmeasured.values() for n in names})
        kinds = sorted(unmeasured.items(), key=lambda kv: -len(kv[1]))
        print(f"imaginary-axis stability not measured for {total} schemes (`longtime list --full` names each): "
              + "; ".join(f"{why} {len(names)}" for why, names in kinds))
    if data["broken"]:
        print("broken plugins:")
        for b in data["broken"]:
            print(f"  {b['group']} '{b['name']}' ({b['target']}): {b['error']}")
    return 0
