"""``nonrigid cache info | clear [--dir DIR]``: the compiled programs kept on disk between runs.

Every ``nonrigid`` run keeps the programs it compiles in a cache folder (:mod:`jaxfem.cache`:
``$XDG_CACHE_HOME/nonrigid/jax`` or ``~/.cache/nonrigid/jax``; ``NONRIGID_CACHE_DIR`` moves it,
``NONRIGID_CACHE=0`` turns it off), so a later run loads them instead of compiling again.
``info`` prints the folder, whether runs use it, its programs and their size; ``clear`` deletes the
programs (only the files the cache wrote; the folder stays).
"""

from __future__ import annotations

import argparse


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``cache`` sub-command to ``subparsers`` (from ``ArgumentParser.add_subparsers``)."""
    p = subparsers.add_parser("cache", help="show or empty the folder of compiled programs kept between runs",
                              description="Compiled programs are kept in a cache folder between runs; "
                              "NONRIGID_CACHE_DIR moves it, NONRIGID_CACHE=0 turns it off.")
    p.add_argument("action", choices=("info", "clear"), help="info: where and how large; clear: delete the programs")
    p.add_argument("--dir", default=None, help="the cache folder (default: the one runs use now)")
    p.set_defaults(run=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Carry out ``nonrigid cache`` (``args`` from the parser of :func:`add_parser`); 0 on success."""
    print(cache(args.action, args.dir))
    return 0


def cache(action: str, folder=None) -> str:
    """``"info"``: a description of the cache folder ``folder`` (default: the one in use, see
    :func:`jaxfem.cache_info`); ``"clear"``: delete its programs (:func:`jaxfem.clear_cache`) and
    say how many. Returns the text printed by ``nonrigid cache``."""
    from jaxfem.cache import cache_info, clear_cache

    if action == "clear":
        info = cache_info(folder)
        if info["dir"] is None:
            return "no cache folder (NONRIGID_CACHE=0 turns the cache off; --dir names one)"
        return f"deleted {clear_cache(folder)} compiled programs ({info['bytes'] / 2**20:.1f} MiB) from {info['dir']}"
    if action != "info":
        raise ValueError(f"unknown cache action {action!r}; use 'info' or 'clear'")
    info = cache_info(folder)
    if info["dir"] is None:
        return "the cache is off (NONRIGID_CACHE=0): every run compiles its programs"
    use = "used by runs now" if info["enabled"] else "not the folder runs use now"
    return (f"{info['dir']} ({use}): {info['entries']} compiled programs, {info['bytes'] / 2**20:.1f} MiB\n"
            "programs that call a host linear solver (pardiso, superlu, cholmod) are not kept")
