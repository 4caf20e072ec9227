"""The `rescuemesh radio-map` and `rescuemesh radio-validate` commands.

Owns: what these two commands do with their parsed arguments and what they print. Must not know:
the radio model's insides (rescuemesh.radio), argument parsing (cli.py).
"""

from __future__ import annotations

from rescuemesh.cli import EXIT_OK, UsageError, _check_seed, _pose, _writable_folder


def radio_map(args) -> int:
    from rescuemesh.maps import MapError, load_map, office_map_path
    from rescuemesh.radio import make_channel
    from rescuemesh.report.radio_map import RadioMapQuantity, write_radio_map

    _check_seed(args.seed)
    x, y = _pose(args.origin, with_yaw=False)
    try:
        map_model = load_map(args.map or office_map_path())
        channel = make_channel(args.radio, grid=map_model.grid, seed=args.seed)
        out = _writable_folder(args.out)
        path = write_radio_map(map_model, channel, (x, y), out / "radio_map.png",
                               quantity=RadioMapQuantity.POWER if args.power else RadioMapQuantity.DELIVERY)
    except (MapError, ValueError) as error:
        raise UsageError(str(error)) from None
    print(f"radio map of a transmitter at ({x:g}, {y:g}) on {map_model.name} ({args.radio} model)")
    print(f"  wrote {path}")
    return EXIT_OK


def radio_validate(args) -> int:
    """Print the model's errors against the packaged BLE data sets and draw radio_validation.png;
    exit 1 when a goal is not met (radio/validation.py)."""
    from rescuemesh.radio import BleParams
    from rescuemesh.radio import validation as v
    from rescuemesh.report.radio_validation import write_validation_plot

    out = _writable_folder(args.out)
    params = BleParams()
    try:
        kolakowski = v.validate_kolakowski(params) if args.data in ("kolakowski", "all") else None
        danis = v.validate_danis(params) if args.data in ("danis", "all") else None
    except v.ValidationDataError as error:
        raise UsageError(str(error)) from None
    goals = []
    for result, text in ((kolakowski, v.format_kolakowski), (danis, v.format_danis)):
        if result is not None:
            print(text(result))
            goals += result.goals
    path = write_validation_plot(out / "radio_validation.png", kolakowski, danis,
                                 decorrelation_m=params.shadowing_decorrelation_m, exponent=params.path_loss_exponent)
    met = sum(g.met for g in goals)
    print(f"goals met: {met} of {len(goals)}" + ("" if met == len(goals) else
          "; not met: " + "; ".join(g.what for g in goals if not g.met)))
    print(f"  wrote {path}")
    return EXIT_OK if met == len(goals) else 1
