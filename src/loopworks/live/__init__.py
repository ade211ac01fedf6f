"""Running the blocks live (issue 16): a simulated field device and a soft controller.

``loopworks device`` runs a scenario's plant blocks (process, valve, sensors, disturbances) as
a simulated field device serving its I/O over Modbus TCP; ``loopworks serve`` runs the
controller side (controllers, compensators) against it on absolute-deadline scans, with its
own OPC UA server. asyncua and pymodbus are imported by these modules only, so the other
commands do not pay for them.
"""
