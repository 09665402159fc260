from rotorlab.cli import console

console()
