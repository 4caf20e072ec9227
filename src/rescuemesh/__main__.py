from rescuemesh.cli import main

raise SystemExit(main())
