"""The device in memory: the plant side of a split scenario behind the same ``read`` /
``write`` / ``status`` calls as the Modbus I/O (:class:`loopworks.live.modbus_io.ModbusIO`),
with no network. For tests of the controller's rules scan by scan, and for the live benchmark
where the network is not what is measured. ``lost`` simulates a lost device: reads give Bad,
no communication, with the last value, and writes fail."""

from __future__ import annotations

from typing import Any

from loopworks.blocks import status as st
from loopworks.live.split import Split


class LoopbackIO:
    """``read()`` gives the plant's outputs that the controller reads; ``write()`` sets the
    plant's inputs and runs one plant scan of the split's dt."""

    def __init__(self, split: Split) -> None:
        self.split = split
        self.plant = split.plant
        self.lost = False
        self.last: dict[str, float] = {}
        self.errors = 0
        self._ports = [(src, self.plant.blocks[src.split(".", 1)[0]],
                        src.split(".", 1)[1]) for _, src in split.to_controller]

    async def read(self) -> dict[str, tuple[float, int]]:
        out: dict[str, tuple[float, int]] = {}
        for src, block, port in self._ports:
            if self.lost:
                self.errors += 1
                out[src] = (self.last.get(src, float("nan")), st.BAD_NO_COMM_LUV
                            if src in self.last else st.BAD_NO_COMM_NO_LUV)
            else:
                value = float(block.y[block._out_index[port]])
                self.last[src] = value
                out[src] = (value, st.GOOD_NC)
        return out

    async def write(self, values: dict[str, float]) -> bool:
        if self.lost:
            self.errors += 1
            return False
        for point, value in values.items():
            block, port = point.split(".", 1)
            self.plant.blocks[block].set_inputs({port: float(value)})
        self.plant.scan(self.split.dt)
        return True

    def status(self) -> dict[str, Any]:
        return {"connected": not self.lost, "read_errors": self.errors, "write_errors": 0,
                "readback_mismatches": 0}
