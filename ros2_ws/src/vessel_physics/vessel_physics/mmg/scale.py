"""
Write an MMG parameter file for the same hull at another length, by Froude's law.

A parameter file states the length it was made for (``L_pp``); models and the
diagnosis refuse it for a vessel of another length. This program writes the
Froude-scaled file: lengths (L_pp, B, d, x_G, D_p, H_R) times lambda = L_new / L_old,
the rudder area times lambda^2, the displacement (so the mass) and constant forces
times lambda^3, constant moments times lambda^4; the non-dimensional hull, propeller
and rudder coefficients unchanged (``vessel_physics.mmg.params.froude_scaled``). It prints
what the vessel file must then say: speeds times sqrt(lambda), propeller speeds and
yaw rates times 1/sqrt(lambda).

Exit status: 0 when the file was written, 2 on a usage error or an unusable file.
"""

import argparse
import math
from pathlib import Path
import sys

import yaml

from vessel_description import VesselError, load_vessel
from vessel_physics.errors import ConfigError
from vessel_physics.files import find_file
from vessel_physics.mmg.family import FAMILY
from vessel_physics.mmg.params import froude_scaled
from vessel_physics.physics_file import load_physics

EXAMPLES = """\
examples:
  scale_physics kvlcc2_mmg_yasukawa2015 --length 320 --rho 1025 --out kvlcc2_full_scale.yaml
  scale_physics kvlcc2_hsva_mmg --vessel my_tanker.yaml --out my_tanker_mmg.yaml
"""


def parse_args(argv):
    """Parse the command line."""
    parser = argparse.ArgumentParser(description=__doc__ + '\n' + EXAMPLES,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('params', metavar='FILE',
                        help='MMG parameter file (format mmg-params/1), or a packaged name')
    target = parser.add_mutually_exclusive_group(required=True)
    target.add_argument('--length', type=float, metavar='M',
                        help='length between perpendiculars to scale to (m)')
    target.add_argument('--vessel', metavar='FILE',
                        help="take the length from a vessel file's particulars.length_m")
    parser.add_argument('--rho', type=float, metavar='KG_M3',
                        help="water density of the scaled file (default: the source file's)")
    parser.add_argument('--out', required=True, metavar='FILE', help='file to write')
    return parser.parse_args(argv)


def main(argv=None) -> int:
    """Scale, write, report; return the exit status."""
    args = parse_args(argv)
    try:
        path = find_file(args.params, (), 'MMG parameter file')
        physics = load_physics(path)
        if physics.family is not FAMILY:
            raise ConfigError(f'{path}: not an MMG parameter file (format '
                              f'{FAMILY.parameters_format})')
        source = physics.params
        length = args.length
        if args.vessel is not None:
            try:
                length = load_vessel(args.vessel).length_m
            except VesselError as exc:
                raise ConfigError(str(exc)) from None
        if not (length and length > 0) or (args.rho is not None and not args.rho > 0):
            raise ConfigError('--length and --rho must be positive')
        scaled = froude_scaled(source, length, args.rho)
    except ConfigError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    lam = length / source.L_pp
    data = {'format': FAMILY.parameters_format, 'description': (
        f"{source.name} scaled by Froude's law to L_pp {length:g} m (lambda {lam:.6g}, "
        f'from {path.name})'), **scaled.__dict__, 'name': f'{source.name}_L{length:g}'}
    header = (f'# Written by scale_physics from {path.name}: lambda = {lam:.6g}. Speeds scale\n'
              f'# by {math.sqrt(lam):.6g}, propeller speeds and yaw rates by '
              f'{1 / math.sqrt(lam):.6g}, times by {math.sqrt(lam):.6g}.\n')
    Path(args.out).write_text(header + yaml.safe_dump(data, sort_keys=False))
    print(f'{args.out}: L_pp {source.L_pp:g} -> {length:g} m (lambda {lam:.4g}); in the vessel '
          f'file: speeds x {math.sqrt(lam):.4g}, propeller speeds and yaw rates x '
          f'{1 / math.sqrt(lam):.4g}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
