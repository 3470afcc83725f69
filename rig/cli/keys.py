"""`rig keys create|register|sign|list`: a rig's signing key and the public keys the store lists."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from rig.cli.common import ConfigError, open_db, resolve_run
from rig.core.dbpath import DB_HELP


def cmd_create(args: argparse.Namespace) -> int:
    """rig keys create: a new Ed25519 key pair for a rig; the private key stays in the key folder."""
    from rig.keys import create_key

    path, fingerprint = create_key(args.rig, args.dir)
    print(f"rig {args.rig}: private key {path} (mode 600), public key fingerprint {fingerprint}")
    print(f"list it in the records with: rig keys register --db DB --rig {args.rig}", file=sys.stderr)
    return 0


def cmd_register(args: argparse.Namespace) -> int:
    """rig keys register: list a rig's public key in the store (RigKeyRegistered)."""
    from rig.keys import key_path, load_signer, register

    signer = load_signer(args.rig, args.dir)
    if signer is None:
        where = key_path(args.rig, args.dir)
        raise ConfigError(f"{where}: no key for rig {args.rig}; create one with rig keys create", "--rig")
    args.create_db = True
    with open_db(args) as store:
        entry = register(store, signer, replace=args.replace)
    if entry is None:
        print(f"rig {args.rig}: key {signer.fingerprint} is registered already; nothing added")
    else:
        print(f"rig {args.rig}: key {signer.fingerprint} registered (seq {entry.seq})")
    return 0


def cmd_sign(args: argparse.Namespace) -> int:
    """rig keys sign: sign a sealed run that has no signature, once the store verifies."""
    from rig.keys import load_signer, recorded_rig, sign_sealed, unlisted_warning

    with open_db(args) as store:
        run_id = resolve_run(store, args.run)
        rig = args.rig or recorded_rig(store, run_id)
        if rig is None:
            raise ConfigError(f"run {run_id} records no rig; give --rig NAME", "--rig")
        signer = load_signer(rig, args.dir)
        if signer is None:
            raise ConfigError(f"no key for rig {rig} in the key folder (rig keys create)", "--rig")
        entry = sign_sealed(store, run_id, signer)
        warning = unlisted_warning(store, signer)
    print(f"run {run_id} signed by rig {rig} (key {signer.fingerprint}) at seq {entry.seq}")
    if warning:
        print(warning, file=sys.stderr)
    return 0


def cmd_list(args: argparse.Namespace) -> int:
    """rig keys list: the registered public keys, oldest first (a replaced key stays listed)."""
    from rig.keys import keys_in

    with open_db(args) as store:
        keys = keys_in(store)
    current = {k.rig: k.seq for k in keys}  # the last registration of each rig wins
    rows: list[dict[str, Any]] = [
        {
            "rig": k.rig,
            "fingerprint": k.fingerprint,
            "public_key": k.public_key,
            "seq": k.seq,
            "registered_utc": k.t_utc,
            "current": current[k.rig] == k.seq,
        }
        for k in keys
    ]
    if args.json:
        json.dump(rows, sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    if not rows:
        print("no rig keys registered")
    for row in rows:
        state = "current" if row["current"] else "replaced"
        print(f"{row['rig']}  {row['fingerprint']}  seq {row['seq']}  {row['registered_utc'][:19]}  {state}")
    return 0


def add_parsers(sub: Any) -> None:
    """`rig keys create|register|sign|list`."""
    p = sub.add_parser("keys", help="a rig's signing key (Ed25519) and the registered public keys")
    keys = p.add_subparsers(dest="keys_command", required=True, metavar="ACTION")
    dir_help = "key folder (default: $RIG_KEY_DIR, else ~/.config/rig/keys)"

    q = keys.add_parser("create", help="create a rig's key pair", description=cmd_create.__doc__)
    q.add_argument("--rig", required=True, metavar="NAME", help="the rig's identity name")
    q.add_argument("--dir", metavar="DIR", help=dir_help)
    q.set_defaults(handler=cmd_create)

    q = keys.add_parser(
        "register", help="list a rig's public key in the store", description=cmd_register.__doc__
    )
    q.add_argument("--db", metavar="FILE", help=DB_HELP)
    q.add_argument("--rig", required=True, metavar="NAME", help="the rig's identity name")
    q.add_argument("--dir", metavar="DIR", help=dir_help)
    q.add_argument("--replace", action="store_true", help="register a new key for a rig that has one")
    q.set_defaults(handler=cmd_register)

    q = keys.add_parser("sign", help="sign a sealed run that has no signature", description=cmd_sign.__doc__)
    q.add_argument("--db", metavar="FILE", help=DB_HELP)
    q.add_argument("--run", required=True, metavar="RUN", help="run id (a unique prefix will do), or 'last'")
    q.add_argument("--rig", metavar="NAME", help="the signing rig (default: the one the run recorded)")
    q.add_argument("--dir", metavar="DIR", help=dir_help)
    q.set_defaults(handler=cmd_sign)

    q = keys.add_parser("list", help="the registered public keys", description=cmd_list.__doc__)
    q.add_argument("--db", metavar="FILE", help=DB_HELP)
    q.add_argument("--json", action="store_true", help="print JSON")
    q.set_defaults(handler=cmd_list)
