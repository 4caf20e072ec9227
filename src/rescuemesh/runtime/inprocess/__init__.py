"""One process: the MuJoCo world, the simulated radio medium and every robot's brain, stepped together
(sim_loop.SimRuntime). The fastest way to run a scenario, and the reference the other runtimes match."""
