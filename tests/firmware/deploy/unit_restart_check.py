#!/usr/bin/env python3
"""Would systemd restart the installed haptic-station unit after a safety stop?

Usage: unit_restart_check.py UNIT_FILE FIRMWARE_DIR

Reads the safety-stop exit codes from the firmware's kSafetyStopExitCodes (by name, their values
from the ExitCode enum; wherever the header lives under FIRMWARE_DIR), adds the crash signals (a
station killed by SIGABRT/SIGSEGV/SIGBUS/SIGFPE/SIGILL stopped force output without writing why),
and applies systemd.service(5)'s restart rules (Restart=, RestartPreventExitStatus=,
RestartForceExitStatus=, SuccessExitStatus=; repeated keys accumulate, an empty one resets) to the
[Service] section of UNIT_FILE. Prints what systemd would do for every exit code of the station
and each signal; exit 1 if any safety stop would be restarted, 2 if the inputs cannot be read.
"""
import pathlib
import re
import sys

CRASH_SIGNALS = ["SIGABRT", "SIGSEGV", "SIGBUS", "SIGFPE", "SIGILL"]
CLEAN_SIGNALS = {"SIGHUP", "SIGINT", "SIGTERM", "SIGPIPE"}  # systemd's "clean" signals
OTHER_SIGNALS = ["SIGKILL"]


def die(msg):
    print(f"unit_restart_check: {msg}")
    sys.exit(2)


def exit_codes(firmware_dir):
    """{name: value} of the ExitCode enum and the names in kSafetyStopExitCodes."""
    for path in sorted(pathlib.Path(firmware_dir).rglob("*.hpp")):
        text = path.read_text(errors="replace")
        m = re.search(r"kSafetyStopExitCodes\[\]\s*=\s*\{([^}]*)\}", text)
        if not m:
            continue
        values = {n: int(v) for n, v in re.findall(r"\b(kExit\w+)\s*=\s*(\d+)", text)}
        names = [n.strip() for n in m.group(1).split(",") if n.strip()]
        missing = [n for n in names if n not in values]
        if not names or missing:
            die(f"{path}: kSafetyStopExitCodes names {missing or 'nothing'} without a value in the ExitCode enum")
        return values, names, path
    die(f"no kSafetyStopExitCodes under {firmware_dir}")


def service_settings(unit_file):
    settings = {}
    section = None
    for raw in pathlib.Path(unit_file).read_text().splitlines():
        line = raw.strip()
        if not line or line[0] in "#;":
            continue
        if line.startswith("["):
            section = line
            continue
        if section != "[Service]" or "=" not in line:
            continue
        key, value = (s.strip() for s in line.split("=", 1))
        if key == "Restart":
            settings["Restart"] = value
        elif key in ("RestartPreventExitStatus", "RestartForceExitStatus", "SuccessExitStatus"):
            if value == "":
                settings[key] = set()
            else:
                settings.setdefault(key, set()).update(value.split())
    return settings


def normalise(items):
    """Exit statuses as ints, signals as 'SIGxxx' (systemd accepts ABRT or SIGABRT)."""
    out = set()
    for item in items:
        if item.isdigit():
            out.add(int(item))
        else:
            out.add(item if item.startswith("SIG") else "SIG" + item)
    return out


def restarts(status, s):
    """systemd.service(5): does the service restart after `status` (an exit code or a signal)?"""
    prevent = normalise(s.get("RestartPreventExitStatus", set()))
    force = normalise(s.get("RestartForceExitStatus", set()))
    success = normalise(s.get("SuccessExitStatus", set()))
    if status in force:
        return True
    if status in prevent:
        return False
    policy = s.get("Restart", "no")
    if isinstance(status, int):
        clean = status == 0 or status in success
        return {"always": True, "on-success": clean, "on-failure": not clean}.get(policy, False)
    clean = status in CLEAN_SIGNALS or status in success
    if policy == "always":
        return True
    if policy == "on-success":
        return clean
    if policy in ("on-failure", "on-abnormal", "on-abort"):
        return not clean
    return False


def main():
    if len(sys.argv) != 3:
        die("usage: unit_restart_check.py UNIT_FILE FIRMWARE_DIR")
    values, safety_names, header = exit_codes(sys.argv[2])
    s = service_settings(sys.argv[1])
    safety = {values[n] for n in safety_names} | set(CRASH_SIGNALS)
    print(f"unit {sys.argv[1]}: Restart={s.get('Restart', 'no')}, RestartPreventExitStatus="
          f"{' '.join(sorted(s.get('RestartPreventExitStatus', set()))) or '(none)'}")
    print(f"safety stops from {header}: {', '.join(f'{values[n]} ({n})' for n in safety_names)}; crash signals {' '.join(CRASH_SIGNALS)}")
    bad = []
    for status in sorted(values.values()) + CRASH_SIGNALS + OTHER_SIGNALS:
        r = restarts(status, s)
        name = next((n for n, v in values.items() if v == status), "")
        kind = "SAFETY STOP" if status in safety else ""
        print(f"  {status!s:>8} {name:<22} {'restarted' if r else 'stays stopped':<14} {kind}")
        if r and status in safety:
            bad.append(f"{status} {name}".strip())
    if bad:
        print(f"FAIL: the unit restarts after a safety stop (re-arms force output without the operator): {', '.join(bad)}")
        return 1
    print("ok: no safety stop is restarted by the unit")
    return 0


if __name__ == "__main__":
    sys.exit(main())
