"""Certificates for the throwaway PostgreSQL cluster of scripts/services.sh, made fresh for
each run (nothing secret is committed): a CA, the server's certificate signed by it for the
host name `localhost` only (so that verify-full to 127.0.0.1 is a host-name mismatch), and a
second, unrelated CA that must be refused.

    python scripts/pg_certs.py DIR    # writes ca.pem, server.pem, server.key, wrong-ca.pem
"""

import datetime
import sys
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID


def name(cn: str) -> x509.Name:
    return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, cn)])


def certificate(subject, issuer, public_key, signing_key, ca: bool) -> x509.Certificate:
    now = datetime.datetime.now(datetime.timezone.utc)
    b = (x509.CertificateBuilder().subject_name(subject).issuer_name(issuer)
         .public_key(public_key).serial_number(x509.random_serial_number())
         .not_valid_before(now - datetime.timedelta(hours=1))
         .not_valid_after(now + datetime.timedelta(days=7))
         .add_extension(x509.BasicConstraints(ca=ca, path_length=None), critical=True))
    if ca:
        b = b.add_extension(x509.KeyUsage(
            digital_signature=True, key_cert_sign=True, crl_sign=True, content_commitment=False,
            key_encipherment=False, data_encipherment=False, key_agreement=False,
            encipher_only=False, decipher_only=False), critical=True)
    else:
        b = b.add_extension(x509.SubjectAlternativeName([x509.DNSName("localhost")]),
                            critical=False)
    return b.sign(signing_key, hashes.SHA256())


def pem(cert: x509.Certificate) -> bytes:
    return cert.public_bytes(serialization.Encoding.PEM)


def main(out: Path) -> None:
    ca_key, wrong_key, server_key = (ec.generate_private_key(ec.SECP256R1()) for _ in range(3))
    ca = certificate(name("graybox test CA"), name("graybox test CA"), ca_key.public_key(),
                     ca_key, ca=True)
    wrong = certificate(name("another CA"), name("another CA"), wrong_key.public_key(),
                        wrong_key, ca=True)
    server = certificate(name("localhost"), ca.subject, server_key.public_key(), ca_key,
                         ca=False)
    (out / "ca.pem").write_bytes(pem(ca))
    (out / "wrong-ca.pem").write_bytes(pem(wrong))
    (out / "server.pem").write_bytes(pem(server))
    key = out / "server.key"
    key.write_bytes(server_key.private_bytes(serialization.Encoding.PEM,
                                             serialization.PrivateFormat.PKCS8,
                                             serialization.NoEncryption()))
    key.chmod(0o600)  # PostgreSQL refuses a key others may read


if __name__ == "__main__":
    main(Path(sys.argv[1]))
