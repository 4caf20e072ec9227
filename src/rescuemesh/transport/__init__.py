"""Transports: thin pumps that move frames between sans-IO network stacks.

Owns: the simulated radio medium (airtime, queues, collisions; transport.sim_medium, which needs
the sim extra through the channel model), the Zenoh link (transport.zenoh_link) and the BLE bearer
(bumble, transport.ble). Each is imported from its module, so a robot process that uses one
loads none of the others' dependencies. Must not know: robots, behaviours, what frames mean.
"""
