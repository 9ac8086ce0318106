"""The radio world: the shared LoRa channel (timing, path loss through walls, collisions,
half duplex, injected faults) and the virtual RN2483 modems that real drivers talk to.
The firmware never imports this package."""
